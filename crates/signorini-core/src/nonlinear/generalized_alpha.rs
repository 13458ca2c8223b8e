//! The nonsmooth generalized-α scheme for nonlinear Lagrangian systems with bilateral joints
//! and unilateral contacts: Chen, Acary, Virlez & Brüls 2013, "A nonsmooth generalized-α scheme
//! for flexible multibody systems with unilateral constraints" (IJNME 96:487–511,
//! doi:10.1002/nme.4568), with the simultaneous enforcement of the constraints at position and
//! velocity levels of Brüls, Acary & Cardona 2014 (CMAME 281:131–161,
//! doi:10.1016/j.cma.2014.07.025), in its decoupled three-stage form. The papers were not at
//! hand when this was written: their equations are cited by what they do, not by number. For a
//! linear system without joints the smooth stage is Acary 2016, (25a), (25e)–(25g).
//!
//! The velocity is split into a smooth part, integrated by the generalized-α method of Chung &
//! Hulbert with Newton iterations on the nonlinear equations of motion, and an impulsive
//! correction; the positions get a correction of their own that removes the drift of the
//! joints and the penetration of the contacts. One step from (t_k, q_k, v_k, a_k, q̈_k):
//!
//! ```text
//! smooth stage (generalized-α, joints at acceleration level, Newton on (q̈, λ)):
//!   (1 − α_m) a_{k+1} + α_m a_k = (1 − α_f) q̈_{k+1} + α_f q̈_k
//!   q̃ = q_k + h v_k + h²(½ − β) a_k + h² β a_{k+1}
//!   ṽ = v_k + h(1 − γ) a_k + h γ a_{k+1}
//!   M(q̃) q̈_{k+1} = F(t_{k+1}, q̃, ṽ) − G(q̃)ᵀ λ_{k+1},    G q̈_{k+1} + κ(t_{k+1}, q̃, ṽ) = 0
//! position stage (Newton on ν, a mixed LCP per iterate):
//!   q_{k+1} = q̃ + M(q̃)⁻¹ C(q̃)ᵀ ν,    g(q_{k+1}, t_{k+1}) = 0 (ν_B free),
//!   0 ≤ g_α(q_{k+1}, t_{k+1}) ⊥ ν_α ≥ 0 on the index set I = {α : g_α(q̃, t_{k+1}) ≤ 0}
//! velocity stage (one mixed LCP):
//!   v_{k+1} = ṽ + M(q_{k+1})⁻¹ C(q_{k+1})ᵀ Λ,    G v_{k+1} + g_t = 0 (Λ_B free),
//!   0 ≤ U^α_{k+1} + e_α U^α_k ⊥ Λ_α ≥ 0 on I (Newton's impact law)
//! ```
//!
//! F = −∇V − c + f are the smooth forces, G = ∂g/∂q the joint Jacobian, κ = d/dt(G v + g_t) at
//! q̈ = 0 (the joints' curvature term, so that the smooth stage keeps g̈ = 0), H_α = ∇g_α the
//! gap Jacobians, C = [G; H_I] the rows of the joints and the contacts of the index set, and
//! U = H v + ∂g/∂t the contacts' local velocities; U_k is U at the start of the step seen
//! through H(q_{k+1}), as in the nonlinear Moreau–Jean scheme. The smooth contact forces are
//! not part of the smooth stage: a lasting contact is held by the two corrections, step after
//! step (the first-order part of the scheme, which Chen et al. 2013 remove with an
//! acceleration-level complementarity in the smooth stage). The joint multipliers λ are
//! reported with the sign of the SOI2 schemes (M q̈ = F − Gᵀλ), so that the `lambda_j` columns
//! of both agree.
//!
//! Coefficients from ρ∞ (Chung & Hulbert 1993; Acary 2016, (26)–(27)): α_m = (2ρ∞ − 1)/(ρ∞ + 1),
//! α_f = ρ∞/(ρ∞ + 1), γ = ½ + α_f − α_m, β = ¼(γ + ½)². Between impacts the scheme is the
//! generalized-α method on the index-1 form of the joints followed by a projection onto
//! g = 0 and G v + g_t = 0, whose corrections are of the size of the local drift, O(h³): second
//! order in q, v and λ (measured in `tests/nonlinear_ns_alpha.rs`).
//!
//! Newton's iteration matrix of the smooth stage is the exact Jacobian of its residual
//! r = (M(q̃) q̈ + G(q̃)ᵀλ − F(t, q̃, ṽ), G(q̃) q̈ + κ(t, q̃, ṽ)) in (q̈, λ), with q̃ and ṽ moving
//! with q̈ by ∂q̃/∂q̈ = h²β' and ∂ṽ/∂q̈ = hγ' (γ' = γ(1 − α_f)/(1 − α_m),
//! β' = β(1 − α_f)/(1 − α_m)):
//!
//! ```text
//! S = [ M + h²β'(∂(M q̈)/∂q + ∂(Gᵀλ)/∂q − ∂F/∂q) − hγ' ∂F/∂v     Gᵀ ]
//!     [ G + h²β' ∂(G q̈ + κ)/∂q + hγ' ∂κ/∂v                      0  ]
//! ```
//!
//! every derivative exact ([`JointedSystem::mass_derivative`],
//! [`JointedSystem::joint_force_derivative`], [`JointedSystem::joint_acceleration_derivatives`]
//! — for a `lagrangian` model symbolic tapes, [`crate::lagrangian::newton_terms`] — and ∂F/∂q,
//! ∂F/∂v with the Coriolis terms), so the smooth stage converges quadratically.
//! Under `newton = "simplified"` (`NewtonStrategy::Simplified`; full Newton is the default
//! here) S is kept from iterate to iterate and from step to step while each iterate solved with
//! it contracts the residual at least by [`SIMPLIFIED_CONTRACTION`], and formed again at the
//! current iterate otherwise (or when its solve fails); the iteration then starts from q̈ and λ
//! extrapolated linearly from the last two steps, O(h²) from the solution where the last
//! step's values are O(h) from it. A checkpoint keeps where S was formed, and a resumed run
//! forms it there again. Same residual test; the converged step differs from full Newton's
//! within the tolerance. On A02 (callgrind, instructions per step over t ∈ [0.3, 0.6] s or
//! [0.3, 0.4] s): N = 10 (dense stages) 0.78 M → 0.64 M, N = 40 1.34 M → 1.31 M, N = 160
//! 5.34 M → 5.00 M, at 2.0–2.4 iterates a step and one S every 2–3 steps: a residual
//! (M, F, G and κ at the iterate) costs a third of a new S there.
//!
//! Its convergence test is on the residual, each block relative to the size of its terms:
//! the dynamics rows against s = max_i (Σ_j |M_ij q̈_j| + Σ_j |G_ji λ_j| + |F_i|), the joint
//! rows as the generalized force that would remove them, |r_j| ‖M‖∞ / ‖G_j‖∞, against the
//! same s. (Measuring a joint row against |G_j q̈| + |κ_j| instead failed on the regular
//! two-loop four-bar: on its parallelogram motion both vanish, and the round-off of r_j,
//! 10⁻¹⁷, was 3 % of that scale at every iterate.) When S is singular because the joints
//! have lost rank (a singular position, redundant joints: docs/soi2.md) the increment is the
//! minimum-norm least-squares one of [`crate::soi2::factor::NewtonFactor`]; when the joints
//! were rank-deficient at the start of the step (on the manifold, where the rank is sharp),
//! every S of the step is solved at least that deficient, since off the manifold the
//! near-null singular values of G(q̃) are small but not zero and a regular solve would put an
//! unbounded component into λ ([`factor_saddle`]). The position
//! stage uses the exact derivative of g(q̃ + M̃⁻¹C̃ᵀν) in ν, C(q^i) M̃⁻¹ C̃ᵀ (quadratic
//! convergence). The mixed LCPs are plain problems for [`crate::lcp::solve_mixed`], which
//! eliminates the joint rows by their Schur complement (minimum-norm when the joints are
//! dependent) and hands the contact rows to `lcp::solve`. When only joints are in a stage and
//! the model's Delassus operator G M⁻¹ Gᵀ has a band ([`JointedSystem::joint_structure`]:
//! M block diagonal, a chain of joints), the stage forms it from M's blocks and G's nonzeros
//! and solves its equality rows by a band LU ([`super::delassus`]), the same Newton iterate
//! and impulses in O(n) instead of O(n³); a step whose band operator is singular to working
//! precision takes the dense path and its minimum-norm solve.
//!
//! Energy (as for the nonlinear Moreau–Jean scheme): `kinetic` = ½ vᵀM(q)v, `potential` =
//! V(q, t), `work_ext` = ½(f_k + f_{k+1})·(q_{k+1} − q_k) (the applied forces, trapezoidal
//! against the displacement, so that a position correction is counted with the rest of the
//! step), `work_contact` = Σ_{α∈I} Λ_α H_α(q_{k+1})·½(ṽ + v_{k+1}) — the change of kinetic
//! energy the contact impulses make, exactly (for a fixed obstacle ½(U_{k+1} + Ũ)Λ, ≤ 0 at an
//! impact since U_{k+1} = −e U_k) — `work_friction` (below, 0 without friction) and
//! `energy_error` = ΔE − work_ext − work_contact − work_friction: the error of the smooth stage,
//! of the position correction and of the joint projection. Without contacts it shrinks as h²
//! over a fixed time.
//!
//! Coulomb friction (planar: one tangent per contact, tangential relative position τ_α(q, t),
//! tangent row T_α = ∇_q τ_αᵀ; Moreau 1988; Acary & Brogliato 2008, ch. 12–13) acts in the
//! velocity stage, the one stage with impulses: when some contact of the index set has μ > 0,
//! its rows are `[G; H_1; T_1; …; H_k; T_k]` at q_{k+1}, the operator C M⁻¹ Cᵀ, the free
//! values (G ṽ + g_t, then per contact H_α ṽ + ∂g_α/∂t + e_α U^α_k and T_α ṽ + ∂τ_α/∂t), and
//! the problem is the planar friction problem (Signorini and Newton's impact law in the
//! normal rows, Coulomb's law on U_t,{k+1} = T v_{k+1} + ∂τ/∂t in the tangent rows) with the
//! joint rows condensed out exactly, as under the nonlinear Moreau–Jean scheme
//! ([`super::moreau_jean`]: [`crate::lcp::EqualityElimination`], then
//! [`crate::friction::solve_friction`]). The smooth stage and the position stage are unchanged:
//! a sliding contact's friction is an impulse of the velocity stage at every step, as its
//! normal reaction is. Without friction on the index set the step is the frictionless one,
//! operation for operation.
//!
//! The tangential impulse's work is, like the normal one, the change of kinetic energy it
//! makes: W_t = P_t T_α(q_{k+1}) · ½(ṽ + v_{k+1}) (v_{k+1} − ṽ = M⁻¹Cᵀ(Λ, P) makes
//! ½ v_{k+1}ᵀMv_{k+1} − ½ ṽᵀMṽ = Σ of these terms exactly), split between `work_friction` and
//! `work_contact` by [`crate::friction::split_tangential_work`] with θ = ½, the start velocity
//! ṽ and the end velocity v_{k+1}: `work_friction` = W_t unless P_t T ṽ > 0 (the tangential
//! velocity reversed within the impulse), then ½ P_t T v_{k+1} ≤ 0 and the rest goes to
//! `work_contact`. For a fixed surface (∂τ/∂t = 0) T v_{k+1} is U_t,{k+1}, on which Coulomb's
//! law makes P_t U_t ≤ 0, so `work_friction` ≤ 0 at every step; a moving surface (∂τ/∂t ≠ 0)
//! can drive the body, and its work on the body, which is what the ledger counts, may be
//! positive.

use super::delassus::{JointCompliance, JointRows, JointStructure};
pub use super::joints::JointedSystem;
use super::moreau_jean::{
    NewtonOptions, NonlinearRunStats, NonlinearState, NonlinearStepError, NonlinearStepReport,
    ParamError, StepAt, contact_columns, has_friction, probe_columns, solve_joint_friction_at,
    solve_mixed_at, stacked_row,
};
use crate::contact::LcpStats;
use crate::dense::{amax, dot, lu_factor};
use crate::friction;
use crate::lcp::LcpOptions;
use crate::observer::Columns;
use crate::soi2::banded::{BandLu, BandOrder};
use crate::soi2::factor::{NewtonFactor, numerical_rank, pivot_range};
use crate::soi2::method::NewtonStrategy;
use crate::triplets::Triplets;
use nalgebra::{DMatrix, DVector};

/// How far above the Newton tolerance the smooth stage accepts a residual that stopped
/// shrinking (by half per iteration) on a singular Newton matrix (rank-deficient joints).
pub const STALL_FACTOR: f64 = 100.0;

/// Parameters of the scheme.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NsAlphaParams {
    /// α_m < 1.
    pub alpha_m: f64,
    /// α_f < 1.
    pub alpha_f: f64,
    /// β > 0.
    pub beta: f64,
    /// γ > 0.
    pub gamma: f64,
    /// Newton's settings, for the smooth stage (relative residual) and the position stage
    /// (constraint violation relative to the constraints' scale).
    pub newton: NewtonOptions,
    /// How the smooth stage gets its Newton matrix S: formed at every iterate (`Full`, the
    /// default here: quadratic convergence) or kept across iterates and steps while it
    /// contracts the residual (`Simplified`, module documentation).
    pub strategy: NewtonStrategy,
}

impl NsAlphaParams {
    /// Chung–Hulbert coefficients from the spectral radius at infinity ρ∞ ∈ [0, 1] (Acary 2016,
    /// (26)–(27)), default Newton settings.
    pub fn from_rho_inf(rho_inf: f64) -> Self {
        let alpha_m = (2.0 * rho_inf - 1.0) / (rho_inf + 1.0);
        let alpha_f = rho_inf / (rho_inf + 1.0);
        let gamma = 0.5 + alpha_f - alpha_m;
        Self {
            alpha_m,
            alpha_f,
            beta: 0.25 * (gamma + 0.5) * (gamma + 0.5),
            gamma,
            newton: NewtonOptions::default(),
            strategy: NewtonStrategy::Full,
        }
    }
}

/// What one step produced besides the new state.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct NsAlphaStepReport {
    /// Energies, works, gaps g(q_{k+1}), local velocities U_{k+1}, contact impulses Λ, the
    /// velocity stage's LCP and the smooth stage's Newton iterations, as the nonlinear
    /// Moreau–Jean scheme reports them.
    pub base: NonlinearStepReport,
    /// Joint multipliers λ_{k+1} of the smooth stage (M q̈ = F − Gᵀλ).
    pub lambda: Vec<f64>,
    /// Joint impulses Λ_B of the velocity stage (the O(h³) velocity projection).
    pub joint_impulse: Vec<f64>,
    /// U_k = H(q_{k+1}) v_k + ∂g/∂t(q_{k+1}, t_k) of the contacts in the index set, the local
    /// velocity the impact law multiplies by −e (0 outside the index set).
    pub local_velocity_before: Vec<f64>,
    /// Whether each contact was in the index set.
    pub in_index_set: Vec<bool>,
    /// max |g(q_{k+1}, t_{k+1})| over the joints.
    pub position_residual: f64,
    /// max |G v_{k+1} + g_t| over the joints.
    pub velocity_residual: f64,
    /// max(0, −min_α g_α(q_{k+1}, t_{k+1})).
    pub penetration: f64,
    /// Newton iterates of the position stage (0 when nothing was corrected).
    pub position_iterations: usize,
    /// The numerical rank of the joint Jacobian G(q_{k+1}) when the smooth stage met a
    /// singular Newton matrix for want of joint rank (a singular position, redundant joints)
    /// and took the minimum-norm increment; `None` on a regular step.
    #[serde(default)]
    pub joint_rank: Option<usize>,
    /// Newton matrices the smooth stage formed and factorised (its iterations under full
    /// Newton; 0 on a step that solved with a kept one under simplified Newton).
    #[serde(default)]
    pub newton_matrices: usize,
}

impl NsAlphaStepReport {
    /// A report of `state` (no step taken).
    pub fn of_state<S: JointedSystem + ?Sized>(system: &S, state: &NonlinearState) -> Self {
        let (m, nb) = (system.contacts(), system.joints());
        let base = NonlinearStepReport::of_state(system, state);
        let mut g = vec![0.0; nb];
        system.joint_values(state.t, &state.q, &mut g);
        let mut r = vec![0.0; nb];
        system.joint_rates(state.t, &state.q, &state.v, &mut r);
        Self {
            penetration: base.gap.iter().fold(0.0f64, |p, &x| p.max(-x)),
            base,
            lambda: vec![0.0; nb],
            joint_impulse: vec![0.0; nb],
            local_velocity_before: vec![0.0; m],
            in_index_set: vec![false; m],
            position_residual: amax(&g),
            velocity_residual: amax(&r),
            position_iterations: 0,
            joint_rank: None,
            newton_matrices: 0,
        }
    }
}

/// What the next step of the scheme reads besides the state: the end of the last step, kept as
/// the start of the next (a_k, q̈_k, λ_k, f_k and E_k, with the state they belong to: a state
/// changed between steps is made consistent afresh), and for simplified Newton q̈_{k−1}, λ_{k−1}
/// and where its kept matrix was formed. This is all a checkpoint keeps of the scheme; the
/// Delassus operators, and the Newton matrix under full Newton, are formed by each step.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(crate) struct NsAlphaMemory {
    step: u64,
    t: f64,
    q: Vec<f64>,
    v: Vec<f64>,
    /// Pseudo-acceleration a_k.
    a: Vec<f64>,
    /// Acceleration q̈_k of the smooth stage.
    acc: Vec<f64>,
    lambda: Vec<f64>,
    applied: Vec<f64>,
    energy: f64,
    /// Where the smooth stage's kept Newton matrix was formed (simplified Newton): a resumed
    /// run forms the same S there again, so that it goes on bit for bit.
    #[serde(default)]
    matrix_at: Option<MatrixPoint>,
    /// q̈_{k−1} and λ_{k−1}, from which simplified Newton extrapolates its start (`None` on
    /// a start made consistent afresh).
    #[serde(default)]
    before: Option<(Vec<f64>, Vec<f64>)>,
    /// The numerical rank of G(q_k) when it is below the joints' count (the step that ended at
    /// q_k, or the consistent start, met rank-deficient joints): the next smooth stage's
    /// Newton matrices are then solved at a rank deficit of at least the joints' (see
    /// [`factor_saddle`]).
    #[serde(default)]
    joint_rank: Option<usize>,
}

/// The iterate at which the smooth stage formed a Newton matrix S: the step's time t_{k+1},
/// q̃, ṽ, q̈ and λ. S is a function of these alone (and of h and the coefficients).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub(crate) struct MatrixPoint {
    t: f64,
    q: Vec<f64>,
    v: Vec<f64>,
    acc: Vec<f64>,
    lambda: Vec<f64>,
}

/// The smooth stage's Newton matrix kept across iterates and steps (simplified Newton): where
/// it was formed, and its factors (`None` after a restore until the next iterate forms them
/// again at `at`).
#[derive(Debug, Clone)]
struct KeptMatrix {
    at: MatrixPoint,
    factor: Option<NewtonFactor>,
}

/// Simplified Newton keeps S while each iterate it solves with reduces the smooth stage's
/// residual at least by this factor; a slower contraction re-forms S at the current iterate.
/// From the extrapolated start (a residual of about 2.5e-6 on A02) two iterates at 0.01 reach
/// the tolerance 1e-10, and S's contraction ratio grows by about 1e-3 per step of its age, so
/// S lasts about ten steps. Measured on A02, N = 40, t ∈ [0.3, 0.6] s (callgrind, instructions
/// per step): 1.374 M at 0.03 (2.8 iterates a step), 1.370 M at 0.01, 1.439 M at 0.003 (one S
/// every 1.5 steps).
pub const SIMPLIFIED_CONTRACTION: f64 = 0.01;

/// The nonsmooth generalized-α scheme for one system and one step size.
#[derive(Debug, Clone)]
pub struct NonsmoothGeneralizedAlpha {
    params: NsAlphaParams,
    h: f64,
    lcp: LcpOptions,
    n: usize,
    m: usize,
    nb: usize,
    /// μ_α per contact.
    mu: Vec<f64>,
    /// Whether some contact has μ > 0 (the tangent rows are then formed at the end of each
    /// step, for the tangential velocities).
    pub(super) friction: bool,
    last: Option<NsAlphaMemory>,
    /// The smooth stage's Newton matrix under simplified Newton.
    kept: Option<KeptMatrix>,
}

/// What the smooth stage hands to the corrections: a_{k+1}, q̈_{k+1}, λ_{k+1}, the predicted
/// q̃ and ṽ, M(q̃) and G(q̃), and its Newton iterates.
struct SmoothStage {
    a1: Vec<f64>,
    acc: Vec<f64>,
    lambda: Vec<f64>,
    qt: Vec<f64>,
    vt: Vec<f64>,
    mass: Triplets,
    gj: Triplets,
    iterations: usize,
    /// Newton matrices formed and factorised.
    matrices: usize,
    /// An iterate's Newton matrix was singular with the joints rank-deficient (solved by the
    /// minimum-norm increment).
    deficient: bool,
}

/// The rows the velocity stage works on, at q_{k+1}: M, G, H, ∂g/∂t at t_{k+1} and at t_k,
/// and for a system with friction T and ∂τ/∂t at t_{k+1} (empty otherwise).
struct EndRows {
    mass: Triplets,
    gj: Triplets,
    hj: Vec<f64>,
    tj: Vec<f64>,
    rates1: Vec<f64>,
    rates0: Vec<f64>,
    trates1: Vec<f64>,
}

/// What the velocity stage hands to the end of the step: v_{k+1}, the rows at q_{k+1} and the
/// impulses' works (`work_contact`, `work_friction`).
struct VelocityStage {
    v: Vec<f64>,
    rows: EndRows,
    work_contact: f64,
    work_friction: f64,
}

/// The velocity stage's problem: the start of the step (v_k), ṽ, q_{k+1} and the index set.
struct Impact<'a> {
    start: &'a NsAlphaMemory,
    vt: &'a [f64],
    q: &'a [f64],
    active: &'a [usize],
}

/// A row-major matrix as an nalgebra matrix.
fn mat(rows: usize, cols: usize, data: &[f64]) -> DMatrix<f64> {
    DMatrix::from_row_slice(rows, cols, data)
}

/// The Delassus operator `C M⁻¹ Cᵀ` of the constraint rows `C` (stacked as a matrix) at
/// q_{k+1}, and `M⁻¹ Cᵀ`, which maps the stage's impulses to its velocity jump.
fn delassus(
    rows: &DMatrix<f64>,
    mass: &Triplets,
    at: StepAt,
) -> Result<(DMatrix<f64>, DMatrix<f64>), NonlinearStepError> {
    let m_lu = MassFactor::new(mass).ok_or_else(|| at.singular(0))?;
    let y = m_lu
        .solve(&rows.transpose())
        .ok_or_else(|| at.singular(0))?;
    Ok((rows * &y, y))
}

/// LU factors of a mass matrix given as its entries: in its reverse Cuthill–McKee band order
/// when its structure makes the band LU pay (a long chain's banded M: no n×n array), else
/// dense, as before (the small and the dense models keep their bits).
enum MassFactor {
    Dense(nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn>),
    Band(BandLu),
}

impl MassFactor {
    /// The factors of `mass`, `None` when it is singular to working precision (a pivot at or
    /// below n ε times the largest entry of its column, [`crate::dense::negligible_pivot`]).
    fn new(mass: &Triplets) -> Option<MassFactor> {
        let n = mass.rows();
        match BandOrder::of_entries(n, mass.entries().iter().map(|&(i, j, _)| (i, j))) {
            Some(band) => BandLu::factor_regular(&band, mass.entries()).map(MassFactor::Band),
            None => lu_factor(mat(n, n, &mass.to_dense())).map(MassFactor::Dense),
        }
    }

    /// M⁻¹ B.
    fn solve(&self, b: &DMatrix<f64>) -> Option<DMatrix<f64>> {
        match self {
            MassFactor::Dense(lu) => lu.solve(b),
            MassFactor::Band(lu) => {
                let mut x = b.clone();
                for mut column in x.column_iter_mut() {
                    if !lu.solve_mut(column.as_mut_slice()) {
                        return None;
                    }
                }
                Some(x)
            }
        }
    }
}

/// The velocity jump of the impulses `z`: `v += M⁻¹ Cᵀ z` (`y` = `M⁻¹ Cᵀ` from [`delassus`]).
fn apply_impulse(
    y: &DMatrix<f64>,
    z: &[f64],
    v: &mut [f64],
    at: StepAt,
) -> Result<(), NonlinearStepError> {
    let dv = y * DVector::from_column_slice(z);
    for (vi, d) in v.iter_mut().zip(dv.iter()) {
        *vi += d;
    }
    at.check(v, "the velocities")
}

impl NonsmoothGeneralizedAlpha {
    /// Prepares the scheme for `system` with step `h`. Errors name the parameter.
    pub fn new<S: JointedSystem + ?Sized>(
        system: &S,
        params: NsAlphaParams,
        h: f64,
        lcp: LcpOptions,
    ) -> Result<Self, ParamError> {
        let bad = |field, reason: String| Err(ParamError { field, reason });
        if !(h.is_finite() && h > 0.0) {
            return bad("h", format!("must be a finite number > 0, got {h}"));
        }
        for (field, x) in [
            ("alpha_m", params.alpha_m),
            ("alpha_f", params.alpha_f),
            ("beta", params.beta),
            ("gamma", params.gamma),
        ] {
            if !x.is_finite() {
                return bad(field, format!("must be finite, got {x}"));
            }
        }
        if params.alpha_m >= 1.0 {
            return bad("alpha_m", format!("must be < 1, got {}", params.alpha_m));
        }
        if params.alpha_f >= 1.0 {
            return bad(
                "alpha_f",
                format!(
                    "must be < 1 (α_f = 1 leaves q̈_(k+1) undetermined), got {}",
                    params.alpha_f
                ),
            );
        }
        if params.beta <= 0.0 {
            return bad("beta", format!("must be > 0, got {}", params.beta));
        }
        if params.gamma <= 0.0 {
            return bad("gamma", format!("must be > 0, got {}", params.gamma));
        }
        let newton = params.newton;
        if !(newton.tolerance.is_finite() && newton.tolerance > 0.0) {
            return bad(
                "newton_tolerance",
                format!("must be a finite number > 0, got {}", newton.tolerance),
            );
        }
        if newton.max_iterations == 0 {
            return bad("newton_max_iterations", "must be ≥ 1".to_string());
        }
        Ok(Self {
            params,
            h,
            lcp,
            n: system.dofs(),
            m: system.contacts(),
            nb: system.joints(),
            mu: (0..system.contacts()).map(|a| system.friction(a)).collect(),
            friction: has_friction(system),
            last: None,
            kept: None,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &NsAlphaParams {
        &self.params
    }

    /// What the next step reads besides the state (for a checkpoint).
    pub(crate) fn memory(&self) -> Option<&NsAlphaMemory> {
        self.last.as_ref()
    }

    /// Restores the memory of a checkpoint; refused when it does not fit the system.
    pub(crate) fn restore(
        &mut self,
        memory: Option<NsAlphaMemory>,
    ) -> Result<(), crate::checkpoint::CheckpointError> {
        if let Some(e) = &memory
            && (e.q.len() != self.n
                || e.lambda.len() != self.nb
                || e.matrix_at.as_ref().is_some_and(|p| {
                    p.q.len() != self.n
                        || p.v.len() != self.n
                        || p.acc.len() != self.n
                        || p.lambda.len() != self.nb
                })
                || e.before
                    .as_ref()
                    .is_some_and(|(a, l)| a.len() != self.n || l.len() != self.nb))
        {
            return Err(crate::checkpoint::CheckpointError::Mismatch(format!(
                "an ns_generalized_alpha memory of {} coordinates and {} joints, the system has {} and {}",
                e.q.len(),
                e.lambda.len(),
                self.n,
                self.nb
            )));
        }
        self.kept = memory
            .as_ref()
            .and_then(|e| e.matrix_at.clone())
            .map(|at| KeptMatrix { at, factor: None });
        self.last = memory;
        Ok(())
    }

    /// q̈ and λ at (t, q, v) from the smooth equations with the joints at acceleration level:
    /// `[M Gᵀ; G 0][q̈; λ] = [F; −κ]` (the consistent start, a_0 = q̈_0), and whether the
    /// joints were rank-deficient there (λ then the minimum-norm multipliers).
    pub(super) fn consistent<S: JointedSystem + ?Sized>(
        &self,
        system: &S,
        t: f64,
        q: &[f64],
        v: &[f64],
    ) -> Option<(Vec<f64>, Vec<f64>, bool)> {
        let (n, nb) = (self.n, self.nb);
        let mut mass = Triplets::new(n, n);
        system.mass_entries(q, &mut mass);
        let mut f = vec![0.0; n];
        system.forces(t, q, v, &mut f);
        let mut g = Triplets::new(nb, n);
        system.joint_jacobian_entries(t, q, &mut g);
        let mut kappa = vec![0.0; nb];
        system.joint_curvature(t, q, v, &mut kappa);
        let mut k = Triplets::new(n + nb, n + nb);
        for &(i, j, m) in mass.entries() {
            k.push(i, j, m);
        }
        for &(r, i, x) in g.entries() {
            k.push(n + r, i, x);
            k.push(i, n + r, x);
        }
        let rhs = DVector::from_fn(n + nb, |i, _| if i < n { f[i] } else { -kappa[i - n] });
        // Minimum-norm multipliers when the joints are rank-deficient (redundant joints).
        let (x, deficient) = solve_saddle(&k, rhs, &g, system.newton_band())?;
        if x.iter().any(|x| !x.is_finite()) {
            return None;
        }
        Some((
            x.as_slice()[..n].to_vec(),
            x.as_slice()[n..].to_vec(),
            deficient,
        ))
    }

    /// Advances `state` by one step, writing the step's terms into `report` (sized by
    /// [`NsAlphaStepReport::of_state`]). The phases (module documentation): the start of the
    /// step, the smooth stage (the free state of the generalized-α predictor with Newton on
    /// (q̈, λ)), the index set of the predicted gaps, the position stage, the velocity stage
    /// (the one-step nonsmooth problem of Newton's impact law) and the update of the state
    /// with the step's energy terms.
    pub fn step<S: JointedSystem + ?Sized>(
        &mut self,
        system: &S,
        state: &mut NonlinearState,
        report: &mut NsAlphaStepReport,
    ) -> Result<(), NonlinearStepError> {
        let step = state.step + 1;
        let at = StepAt {
            step,
            t: (step as f64) * self.h,
        };
        let start = self.start_of_step(system, state, at)?;
        let mut kept = self.kept.take();
        let smooth = self.smooth_stage(system, &start, at, &mut kept);
        self.kept = kept;
        let smooth = smooth?;
        // Index set: contacts whose predicted gap g(q̃, t_{k+1}) is ≤ 0.
        let mut gaps = vec![0.0; self.m];
        system.gaps(at.t, &smooth.qt, &mut gaps);
        at.check(&gaps, "a gap g(q, t)")?;
        let mut active: Vec<usize> = (0..self.m).filter(|&a| gaps[a] <= 0.0).collect();
        let (q, position_iterations) =
            self.position_stage(system, &start, &smooth, &mut active, at)?;
        report.position_iterations = position_iterations;
        let velocity =
            self.velocity_stage(system, state.t, &start, &smooth, &q, &active, report, at)?;
        self.finish(system, state, start, smooth, q, velocity, report, at)
    }

    /// The start of the step, kept from the last one or made consistent afresh.
    fn start_of_step<S: JointedSystem + ?Sized>(
        &mut self,
        system: &S,
        state: &NonlinearState,
        at: StepAt,
    ) -> Result<NsAlphaMemory, NonlinearStepError> {
        let (n, t_k) = (self.n, state.t);
        if let Some(e) = self.last.take()
            && e.step == state.step
            && e.t == state.t
            && e.q == state.q
            && e.v == state.v
        {
            return Ok(e);
        }
        let (acc, lambda, deficient) = self
            .consistent(system, t_k, &state.q, &state.v)
            .ok_or_else(|| at.singular(0))?;
        let joint_rank = deficient.then(|| {
            let mut g = vec![0.0; self.nb * n];
            system.joint_jacobian(t_k, &state.q, &mut g);
            numerical_rank(&g, self.nb, n)
        });
        let mut applied = vec![0.0; n];
        system.applied_forces(t_k, &state.q, &state.v, &mut applied);
        at.check_at(
            &applied,
            "the applied forces f(t, q, v)",
            &state.q,
            &state.v,
        )?;
        let mut mass = Triplets::new(n, n);
        system.mass_entries(&state.q, &mut mass);
        let energy = 0.5 * mass.quadratic(&state.v) + system.potential(t_k, &state.q);
        if !energy.is_finite() {
            return Err(at.not_finite("the energy", energy));
        }
        Ok(NsAlphaMemory {
            step: state.step,
            t: t_k,
            q: state.q.clone(),
            v: state.v.clone(),
            a: acc.clone(),
            acc,
            lambda,
            applied,
            energy,
            matrix_at: None,
            before: None,
            joint_rank: joint_rank.filter(|&r| r < self.nb),
        })
    }

    /// The smooth stage: the generalized-α predictor q̃, ṽ of a_{k+1} and Newton on
    /// (q̈_{k+1}, λ_{k+1}) with the joints at acceleration level (module documentation). Under
    /// simplified Newton `kept` holds the Newton matrix from iterate to iterate and step to
    /// step.
    fn smooth_stage<S: JointedSystem + ?Sized>(
        &self,
        system: &S,
        start: &NsAlphaMemory,
        at: StepAt,
        kept: &mut Option<KeptMatrix>,
    ) -> Result<SmoothStage, NonlinearStepError> {
        let (h, n, nb, t1) = (self.h, self.n, self.nb, at.t);
        let NsAlphaParams {
            alpha_m,
            alpha_f,
            beta,
            gamma,
            newton,
            strategy,
        } = self.params;
        let simplified = strategy == NewtonStrategy::Simplified;
        // The joints' rank deficit at the start of the step (on the manifold): the Newton
        // matrices at q̃ are solved at least that deficient, and none is kept.
        let redundant = start.joint_rank.map_or(0, |r| nb.saturating_sub(r));
        if redundant > 0 {
            *kept = None;
        }
        let mut x = SmoothStage {
            a1: vec![0.0; n],
            acc: start.acc.clone(),
            lambda: start.lambda.clone(),
            qt: vec![0.0; n],
            vt: vec![0.0; n],
            mass: Triplets::new(n, n),
            gj: Triplets::new(nb, n),
            iterations: 0,
            matrices: 0,
            deficient: false,
        };
        // Simplified Newton starts from q̈ and λ extrapolated linearly from the last two steps:
        // its matrix contracts the residual by a ratio that grows with the matrix's age, so a
        // start O(h²) instead of O(h) from the solution saves iterates.
        if let Some((acc0, lambda0)) = start.before.as_ref().filter(|_| simplified) {
            for (x, (a1, a0)) in x.acc.iter_mut().zip(start.acc.iter().zip(acc0)) {
                *x = 2.0 * a1 - a0;
            }
            for (x, (l1, l0)) in x.lambda.iter_mut().zip(start.lambda.iter().zip(lambda0)) {
                *x = 2.0 * l1 - l0;
            }
        }
        let mut f = vec![0.0; n];
        let mut kappa = vec![0.0; nb];
        // The model's matrices as their nonzeros.
        let (mut mass, mut gj) = (Triplets::new(n, n), Triplets::new(nb, n));
        let mut previous = f64::INFINITY;
        // Whether the last increment was solved with a matrix formed at an earlier iterate.
        let mut reused = false;
        loop {
            for i in 0..n {
                x.a1[i] = ((1.0 - alpha_f) * x.acc[i] + alpha_f * start.acc[i]
                    - alpha_m * start.a[i])
                    / (1.0 - alpha_m);
                x.qt[i] = start.q[i]
                    + h * start.v[i]
                    + h * h * ((0.5 - beta) * start.a[i] + beta * x.a1[i]);
                x.vt[i] = start.v[i] + h * ((1.0 - gamma) * start.a[i] + gamma * x.a1[i]);
            }
            system.mass_entries(&x.qt, &mut mass);
            at.check_entries_at(&mass, "M(q)", &x.qt, &[])?;
            system.forces(t1, &x.qt, &x.vt, &mut f);
            at.check_at(&f, "F(t, q, v)", &x.qt, &x.vt)?;
            system.joint_jacobian_entries(t1, &x.qt, &mut gj);
            system.joint_curvature(t1, &x.qt, &x.vt, &mut kappa);
            at.check_entries_at(&gj, "the joint Jacobian", &[], &[])?;
            at.check(&kappa, "the joints' curvature term")?;
            let (r, residual) = smooth_residual(&x, &mass, &gj, &f, &kappa);
            if !residual.is_finite() {
                return Err(at.not_finite("the Newton residual", residual));
            }
            // Converged; or, on a singular Newton matrix (joints that lost rank), stalled at
            // round-off within STALL_FACTOR of the tolerance: the least-squares increments stop
            // reducing the residual, which sits at the conditioning's round-off (Bricard,
            // step 808: 1.0004e-10 against 1e-10 for the last 18 iterates).
            let stalled = x.deficient
                && residual >= 0.5 * previous
                && residual <= STALL_FACTOR * newton.tolerance;
            if residual <= newton.tolerance || stalled {
                x.mass = mass;
                x.gj = gj;
                return Ok(x);
            }
            // A kept matrix that contracts too slowly is formed again at this iterate.
            if reused && residual > SIMPLIFIED_CONTRACTION * previous {
                *kept = None;
            }
            previous = residual;
            if x.iterations == newton.max_iterations {
                return Err(at.newton_not_converged(x.iterations, residual, newton.tolerance));
            }
            x.iterations += 1;
            let mut dx = DVector::from_column_slice(&r);
            reused = false;
            if let Some(k) = kept.as_mut().filter(|_| simplified) {
                if k.factor.is_none() {
                    // Restored from a checkpoint: S formed again where the run formed (and
                    // counted) it.
                    let (mut m_at, mut g_at) = (Triplets::new(n, n), Triplets::new(nb, n));
                    system.mass_entries(&k.at.q, &mut m_at);
                    system.joint_jacobian_entries(k.at.t, &k.at.q, &mut g_at);
                    k.factor = Some(
                        self.newton_factor(system, &k.at, &m_at, &g_at, redundant, at)?
                            .ok_or_else(|| at.singular(x.iterations))?,
                    );
                }
                reused = k.factor.as_ref().is_some_and(|f| f.solve_mut(&mut dx));
            }
            if !reused {
                let point = MatrixPoint {
                    t: t1,
                    q: x.qt.clone(),
                    v: x.vt.clone(),
                    acc: x.acc.clone(),
                    lambda: x.lambda.clone(),
                };
                let factor = self
                    .newton_factor(system, &point, &mass, &gj, redundant, at)?
                    .ok_or_else(|| at.singular(x.iterations))?;
                x.matrices += 1;
                dx.copy_from_slice(&r);
                if !factor.solve_mut(&mut dx) {
                    return Err(at.singular(x.iterations));
                }
                *kept = None;
                if factor.deficient() {
                    x.deficient = true;
                } else if simplified {
                    *kept = Some(KeptMatrix {
                        at: point,
                        factor: Some(factor),
                    });
                }
            }
            for i in 0..n {
                x.acc[i] -= dx[i];
            }
            for j in 0..nb {
                x.lambda[j] -= dx[n + j];
            }
        }
    }

    /// The smooth stage's Newton matrix S at `p` (module documentation), from M(q̃) and G(q̃)
    /// there (`mass`, `gj`), factorised ([`factor_saddle`], at a rank deficit of at least
    /// `redundant`); None when it is singular other than for want of joint rank, an error when
    /// a derivative is not finite.
    fn newton_factor<S: JointedSystem + ?Sized>(
        &self,
        system: &S,
        p: &MatrixPoint,
        mass: &Triplets,
        gj: &Triplets,
        redundant: usize,
        at: StepAt,
    ) -> Result<Option<NewtonFactor>, NonlinearStepError> {
        let (h, n, nb) = (self.h, self.n, self.nb);
        let NsAlphaParams {
            alpha_m,
            alpha_f,
            beta,
            gamma,
            ..
        } = self.params;
        let c_a = (1.0 - alpha_f) / (1.0 - alpha_m);
        let (bp, gp) = (h * h * beta * c_a, h * gamma * c_a);
        let (mut dfdq, mut dfdv) = (Triplets::new(n, n), Triplets::new(n, n));
        let (mut dmdq, mut dgldq) = (Triplets::new(n, n), Triplets::new(n, n));
        let (mut dgaq, mut dgav) = (Triplets::new(nb, n), Triplets::new(nb, n));
        system.force_jacobian_entries(p.t, &p.q, &p.v, &mut dfdq, &mut dfdv);
        system.mass_derivative(&p.q, &p.acc, &mut dmdq);
        system.joint_force_derivative(p.t, &p.q, &p.lambda, &mut dgldq);
        system.joint_acceleration_derivatives(p.t, &p.q, &p.v, &p.acc, &mut dgaq, &mut dgav);
        for (d, what) in [
            (&dfdq, "∂F/∂q"),
            (&dfdv, "∂F/∂v"),
            (&dmdq, "∂(M q̈)/∂q"),
            (&dgldq, "∂(Gᵀλ)/∂q"),
            (&dgaq, "∂(G q̈ + κ)/∂q"),
            (&dgav, "∂κ/∂v"),
        ] {
            at.check_entries_at(d, what, &[], &[])?;
        }
        // S of the module documentation, entry by entry.
        let mut s = Triplets::new(n + nb, n + nb);
        s.reserve(
            [mass, &dmdq, &dgldq, &dfdq, &dfdv, gj, gj, &dgaq, &dgav]
                .iter()
                .map(|d| d.len())
                .sum(),
        );
        for (d, c) in [
            (mass, 1.0),
            (&dmdq, bp),
            (&dgldq, bp),
            (&dfdq, -bp),
            (&dfdv, -gp),
        ] {
            for &(i, j, v) in d.entries() {
                s.push(i, j, c * v);
            }
        }
        for &(k, i, v) in gj.entries() {
            s.push(n + k, i, v);
            s.push(i, n + k, v);
        }
        for (d, c) in [(&dgaq, bp), (&dgav, gp)] {
            for &(k, j, v) in d.entries() {
                s.push(n + k, j, c * v);
            }
        }
        Ok(factor_saddle(&s, gj, system.newton_band(), redundant))
    }

    /// The position stage: q = q̃ + M(q̃)⁻¹ C(q̃)ᵀ ν with g = 0 on the joints and
    /// 0 ≤ g_α ⊥ ν_α ≥ 0 on the index set; a contact outside it that the correction pushed into
    /// its obstacle joins it and the stage starts again. Returns q_{k+1} and the iterates.
    fn position_stage<S: JointedSystem + ?Sized>(
        &self,
        system: &S,
        start: &NsAlphaMemory,
        smooth: &SmoothStage,
        active: &mut Vec<usize>,
        at: StepAt,
    ) -> Result<(Vec<f64>, usize), NonlinearStepError> {
        let (n, m, nb, t1) = (self.n, self.m, self.nb, at.t);
        let qt = &smooth.qt;
        let mut gaps = vec![0.0; m];
        let mut hj = vec![0.0; m * n];
        let mut q = qt.clone();
        let mut position_iterations = 0;
        // M̃'s LU ([`MassFactor`]), unless the joints' Delassus operator has a band
        // (factorised then when a contact joins the stage or the band path declines).
        let structure = system.joint_structure();
        let mut m_lu = match structure {
            Some(_) => None,
            None => Some(MassFactor::new(&smooth.mass).ok_or_else(|| at.singular(0))?),
        };
        // The weight of coordinate j in a constraint row's scale.
        let weight: Vec<f64> = (0..n)
            .map(|j| qt[j].abs() + (qt[j] - start.q[j]).abs())
            .collect();
        loop {
            let k = nb + active.len();
            if k == 0 {
                break;
            }
            system.gap_jacobian(t1, qt, &mut hj);
            at.check(&hj, "the gap Jacobian")?;
            // The joints alone through their band Delassus operator, G̃ read on the joints'
            // coordinates; the scale as the dense path's, row by row.
            let joints = structure
                .filter(|_| active.is_empty())
                .and_then(|s| Some((s, s.rows(&smooth.gj)?)));
            let (mut banded, mut scale) = (None, 0.0);
            if let Some((s, g)) = &joints {
                scale = (0..nb)
                    .map(|r| s.row_weight(r, g, &weight))
                    .fold(0.0f64, f64::max);
                banded = self.project_joints(system, qt, smooth, s, g, scale, &mut q, at)?;
            }
            position_iterations += match banded {
                Some(iterations) => iterations,
                None => {
                    // C̃ rows and Y = M̃⁻¹ C̃ᵀ (n×k), dense arrays.
                    let rows_t = constraint_rows(&smooth.gj.to_dense(), &hj, active, n);
                    scale = (0..k)
                        .map(|r| {
                            let row = &rows_t[r * n..(r + 1) * n];
                            (0..n).map(|j| row[j].abs() * weight[j]).sum::<f64>()
                        })
                        .fold(0.0f64, f64::max);
                    let lu = match m_lu.take() {
                        Some(lu) => lu,
                        None => MassFactor::new(&smooth.mass).ok_or_else(|| at.singular(0))?,
                    };
                    let ct = mat(k, n, &rows_t);
                    let y = lu.solve(&ct.transpose()).ok_or_else(|| at.singular(0))?;
                    m_lu = Some(lu);
                    self.project_positions(system, qt, active, &y, scale, &mut q, &mut gaps, at)?
                }
            };
            // A contact outside the index set that the correction pushed into its obstacle
            // joins it, and the stage starts again.
            system.gaps(t1, &q, &mut gaps);
            at.check(&gaps, "a gap g(q, t)")?;
            let tol = self.params.newton.tolerance * scale;
            let joined: Vec<usize> = (0..m)
                .filter(|a| !active.contains(a) && gaps[*a] < -tol)
                .collect();
            if joined.is_empty() {
                break;
            }
            active.extend(joined);
            active.sort_unstable();
        }
        Ok((q, position_iterations))
    }

    /// [`Self::project_positions`] for the joints alone (no contact in the index set) through
    /// their band Delassus operator ([`super::delassus`]): each iterate solves
    /// G(q^i) M̃⁻¹ G̃ᵀ ν = −(g(q^i) − G(q^i) M̃⁻¹ G̃ᵀ ν^i) by its band LU, the same Newton
    /// iterate as the mixed LCP's equality rows; the same tests. No gap enters: the caller
    /// evaluates the gaps at the result. `None` when the band path declines (a block of M̃ not
    /// positive definite, an operator singular to working precision: joints that lost rank),
    /// and the dense path takes the stage from q̃ again.
    #[allow(clippy::too_many_arguments)]
    fn project_joints<S: JointedSystem + ?Sized>(
        &self,
        system: &S,
        qt: &[f64],
        smooth: &SmoothStage,
        structure: &JointStructure,
        g: &JointRows,
        scale: f64,
        q: &mut [f64],
        at: StepAt,
    ) -> Result<Option<usize>, NonlinearStepError> {
        let (n, nb, t1, newton) = (self.n, self.nb, at.t, self.params.newton);
        let Some(y) = JointCompliance::new(structure, &smooth.mass, g) else {
            return Ok(None);
        };
        let tol = newton.tolerance * scale;
        q.copy_from_slice(qt);
        let mut nu = vec![0.0; nb];
        let mut gb = vec![0.0; nb];
        let mut g_q = Triplets::new(nb, n);
        // Y ν^i, then the increment M̃⁻¹ G̃ᵀ (ν^{i+1} − ν^i) of the positions.
        let mut y_x = vec![0.0; n];
        let mut b = vec![0.0; nb];
        let mut step = vec![0.0; nb];
        let mut iter = 0;
        loop {
            system.joint_values(t1, q, &mut gb);
            at.check(&gb, "a joint g(q, t)")?;
            let violation = amax(&gb);
            if violation <= tol && iter > 0 {
                return Ok(Some(iter));
            }
            if iter == newton.max_iterations {
                return Err(at.newton_not_converged(iter, violation / scale, newton.tolerance));
            }
            iter += 1;
            // The first iterate is at q̃, where G is G̃ and the derivative the symmetric D.
            let (rows, lu) = if iter == 1 {
                (None, y.delassus())
            } else {
                system.joint_jacobian_entries(t1, q, &mut g_q);
                at.check_entries_at(&g_q, "the joint Jacobian", &[], &[])?;
                let Some(rows) = structure.rows(&g_q) else {
                    return Ok(None);
                };
                let lu = y.operator(&rows);
                (Some(rows), lu)
            };
            let Some(lu) = lu else {
                return Ok(None);
            };
            let c = rows.as_ref().unwrap_or(g);
            // b = g(q^i) − D ν^i, with D ν^i = G(q^i) (Y ν^i); then ν^{i+1} = −D⁻¹ b.
            y_x.fill(0.0);
            y.apply(&nu, &mut y_x);
            for (r, b_r) in b.iter_mut().enumerate() {
                *b_r = gb[r] - structure.row_dot(r, c, &y_x);
            }
            if !lu.solve_mut(&mut b) {
                return Ok(None);
            }
            for ((s, x), v) in step.iter_mut().zip(&b).zip(nu.iter_mut()) {
                *s = -x - *v;
                *v = -x;
            }
            y_x.fill(0.0);
            y.apply(&step, &mut y_x);
            q.copy_from_slice(qt);
            y.apply(&nu, q);
            at.check(q, "the corrected positions")?;
            if at_round_off(&y_x, q) {
                return Ok(Some(iter));
            }
        }
    }

    /// Newton on ν for one index set: each iterate solves the mixed LCP of the constraints
    /// linearised at q^i with the exact derivative C(q^i) M̃⁻¹ C̃ᵀ = C(q^i) Y, until the
    /// violation is below `tolerance × scale` (one iterate at least with joints, so that the
    /// drift of the smooth stage is removed to round-off) or the correction is at round-off.
    /// Returns the iterates.
    #[allow(clippy::too_many_arguments)]
    fn project_positions<S: JointedSystem + ?Sized>(
        &self,
        system: &S,
        qt: &[f64],
        active: &[usize],
        y: &DMatrix<f64>,
        scale: f64,
        q: &mut [f64],
        gaps: &mut [f64],
        at: StepAt,
    ) -> Result<usize, NonlinearStepError> {
        let (n, m, nb, t1, newton) = (self.n, self.m, self.nb, at.t, self.params.newton);
        let k = nb + active.len();
        let tol = newton.tolerance * scale;
        let mut nu = DVector::zeros(k);
        q.copy_from_slice(qt);
        let mut gb = vec![0.0; nb];
        let mut h_q = vec![0.0; m * n];
        let mut g_q = vec![0.0; nb * n];
        let mut iter = 0;
        loop {
            system.joint_values(t1, q, &mut gb);
            system.gaps(t1, q, gaps);
            at.check(&gb, "a joint g(q, t)")?;
            at.check(gaps, "a gap g(q, t)")?;
            let mut c = Vec::with_capacity(k);
            c.extend_from_slice(&gb);
            c.extend(active.iter().map(|&a| gaps[a]));
            let violation = (0..k)
                .map(|r| {
                    if r < nb || nu[r] > 0.0 {
                        c[r].abs()
                    } else {
                        (-c[r]).max(0.0)
                    }
                })
                .fold(0.0f64, f64::max);
            if violation <= tol && (iter > 0 || nb == 0) {
                return Ok(iter);
            }
            if iter == newton.max_iterations {
                return Err(at.newton_not_converged(iter, violation / scale, newton.tolerance));
            }
            iter += 1;
            system.joint_jacobian(t1, q, &mut g_q);
            system.gap_jacobian(t1, q, &mut h_q);
            at.check(&g_q, "the joint Jacobian")?;
            at.check(&h_q, "the gap Jacobian")?;
            let rows = mat(k, n, &constraint_rows(&g_q, &h_q, active, n));
            let d = &rows * y;
            let b = DVector::from_vec(c) - &d * &nu;
            let sol = solve_mixed_at(&d, b.as_slice(), nb, &self.lcp, at, iter)?;
            let nu_new = DVector::from_vec(sol.z);
            let dq = y * (&nu_new - &nu);
            nu = nu_new;
            let q_new = DVector::from_column_slice(qt) + y * &nu;
            q.copy_from_slice(q_new.as_slice());
            at.check(q, "the corrected positions")?;
            if at_round_off(dq.as_slice(), q) {
                system.gaps(t1, q, gaps);
                return Ok(iter);
            }
        }
    }

    /// The velocity stage at q_{k+1}: v = ṽ + M⁻¹ Cᵀ Λ with G v + g_t = 0 and Newton's impact
    /// law 0 ≤ U_{k+1} + e U_k ⊥ Λ ≥ 0 on the index set (one mixed LCP), or, when a contact of
    /// the index set has μ > 0, the planar friction problem with the joint rows condensed out
    /// (module documentation); and the impulses' works.
    #[allow(clippy::too_many_arguments)]
    fn velocity_stage<S: JointedSystem + ?Sized>(
        &self,
        system: &S,
        t_k: f64,
        start: &NsAlphaMemory,
        smooth: &SmoothStage,
        q: &[f64],
        active: &[usize],
        report: &mut NsAlphaStepReport,
        at: StepAt,
    ) -> Result<VelocityStage, NonlinearStepError> {
        let rows = self.end_rows(system, t_k, q, at)?;
        report.base.impulse.fill(0.0);
        report.base.tangent_impulse.fill(0.0);
        report.base.lcp = LcpStats::default();
        report.joint_impulse.fill(0.0);
        report.local_velocity_before.fill(0.0);
        report.in_index_set.fill(false);
        let mut stage = VelocityStage {
            v: smooth.vt.clone(),
            rows,
            work_contact: 0.0,
            work_friction: 0.0,
        };
        let impact = Impact {
            start,
            vt: &smooth.vt,
            q,
            active,
        };
        if active.iter().any(|&a| self.mu[a] > 0.0) {
            self.friction_impact(system, &impact, &mut stage, report, at)?;
        } else if self.nb + active.len() > 0 {
            self.frictionless_impact(system, &impact, &mut stage, report, at)?;
        }
        Ok(stage)
    }

    /// M, G, H, ∂g/∂t at t_{k+1} and t_k at q_{k+1}; with friction T and ∂τ/∂t at t_{k+1}.
    fn end_rows<S: JointedSystem + ?Sized>(
        &self,
        system: &S,
        t_k: f64,
        q: &[f64],
        at: StepAt,
    ) -> Result<EndRows, NonlinearStepError> {
        let (n, m, nb, t1) = (self.n, self.m, self.nb, at.t);
        let mut r = EndRows {
            mass: Triplets::new(n, n),
            gj: Triplets::new(nb, n),
            hj: vec![0.0; m * n],
            tj: Vec::new(),
            rates1: vec![0.0; m],
            rates0: vec![0.0; m],
            trates1: Vec::new(),
        };
        system.mass_entries(q, &mut r.mass);
        at.check_entries_at(&r.mass, "M(q)", &[], &[])?;
        system.joint_jacobian_entries(t1, q, &mut r.gj);
        system.gap_jacobian(t1, q, &mut r.hj);
        at.check_entries_at(&r.gj, "the joint Jacobian", &[], &[])?;
        at.check(&r.hj, "the gap Jacobian")?;
        system.gap_rates(t1, q, &mut r.rates1);
        system.gap_rates(t_k, q, &mut r.rates0);
        at.check(&r.rates1, "∂g/∂t")?;
        at.check(&r.rates0, "∂g/∂t")?;
        if self.friction {
            r.tj = vec![0.0; m * n];
            r.trates1 = vec![0.0; m];
            system.tangent_jacobian(t1, q, &mut r.tj);
            at.check(&r.tj, "the tangent Jacobian")?;
            system.tangent_rates(t1, q, &mut r.trates1);
            at.check(&r.trates1, "∂τ/∂t")?;
        }
        Ok(r)
    }

    /// U_k = H_α(q_{k+1}) v_k + ∂g_α/∂t(t_k) of contact `a` of the index set, kept in the
    /// report, and the free value H_α ṽ + ∂g_α/∂t(t_{k+1}) + e_α U_k of its normal row.
    fn normal_row<S: JointedSystem + ?Sized>(
        &self,
        system: &S,
        impact: &Impact<'_>,
        r: &EndRows,
        a: usize,
        report: &mut NsAlphaStepReport,
    ) -> f64 {
        let row = &r.hj[a * self.n..(a + 1) * self.n];
        let u_k = dot(row, &impact.start.v) + r.rates0[a];
        report.local_velocity_before[a] = u_k;
        report.in_index_set[a] = true;
        dot(row, impact.vt) + r.rates1[a] + system.restitution(a) * u_k
    }

    /// The frictionless velocity stage: the mixed LCP on the rows C = [G; H_I] at q_{k+1},
    /// operator C M⁻¹ Cᵀ, free values (G ṽ + g_t, H ṽ + ∂g/∂t + e U_k).
    fn frictionless_impact<S: JointedSystem + ?Sized>(
        &self,
        system: &S,
        impact: &Impact<'_>,
        stage: &mut VelocityStage,
        report: &mut NsAlphaStepReport,
        at: StepAt,
    ) -> Result<(), NonlinearStepError> {
        let (n, nb, t1) = (self.n, self.nb, at.t);
        let (active, vt) = (impact.active, impact.vt);
        let VelocityStage {
            v,
            rows: r,
            work_contact,
            ..
        } = stage;
        let k = nb + active.len();
        let mut b = vec![0.0; k];
        system.joint_rates(t1, impact.q, vt, &mut b[..nb]);
        // The joints alone with a band Delassus operator: Λ_B = −D⁻¹(G ṽ + g_t) by its band
        // LU, the mixed LCP's equality rows; the dense path when the band path declines.
        if let Some(s) = system.joint_structure().filter(|_| active.is_empty())
            && let Some(g) = s.rows(&r.gj)
            && let Some(y) = JointCompliance::new(s, &r.mass, &g)
            && let Some(lu) = y.delassus()
        {
            let mut z = b.clone();
            if lu.solve_mut(&mut z) {
                z.iter_mut().for_each(|x| *x = -*x);
                y.apply(&z, v);
                at.check(v, "the velocities")?;
                report.joint_impulse.copy_from_slice(&z);
                report.base.lcp = LcpStats::default();
                return Ok(());
            }
        }
        let rows = mat(k, n, &constraint_rows(&r.gj.to_dense(), &r.hj, active, n));
        let (d, y) = delassus(&rows, &r.mass, at)?;
        for (c, &a) in active.iter().enumerate() {
            b[nb + c] = self.normal_row(system, impact, r, a, report);
        }
        let sol = solve_mixed_at(&d, &b, nb, &self.lcp, at, 0)?;
        let z = &sol.z;
        apply_impulse(&y, z, v, at)?;
        report.joint_impulse.copy_from_slice(&z[..nb]);
        for (c, &a) in active.iter().enumerate() {
            let p = z[nb + c];
            report.base.impulse[a] = p;
            if p != 0.0 {
                let row = &r.hj[a * n..(a + 1) * n];
                *work_contact += p * 0.5 * (dot(row, vt) + dot(row, v));
            }
        }
        report.base.lcp = LcpStats {
            size: sol.size,
            iterations: sol.iterations,
            error: sol.error,
        };
        Ok(())
    }

    /// The velocity stage with friction on the index set: the planar friction problem on the
    /// rows `[G; H_1; T_1; …; H_k; T_k]` at q_{k+1}, operator C M⁻¹ Cᵀ, free values
    /// (G ṽ + g_t, then per contact H ṽ + ∂g/∂t + e U_k and T ṽ + ∂τ/∂t), the joint rows
    /// condensed out as under the nonlinear Moreau–Jean scheme
    /// (`moreau_jean::solve_joint_friction_at`); the tangential impulse's work split by
    /// [`friction::split_tangential_work`] with θ = ½ (module documentation).
    fn friction_impact<S: JointedSystem + ?Sized>(
        &self,
        system: &S,
        impact: &Impact<'_>,
        stage: &mut VelocityStage,
        report: &mut NsAlphaStepReport,
        at: StepAt,
    ) -> Result<(), NonlinearStepError> {
        let (n, nb, t1) = (self.n, self.nb, at.t);
        let (active, vt) = (impact.active, impact.vt);
        let VelocityStage {
            v,
            rows: r,
            work_contact,
            work_friction,
        } = stage;
        let size = nb + 2 * active.len();
        let gj = r.gj.to_dense();
        let rows = DMatrix::from_fn(size, n, |i, j| {
            stacked_row(&gj, &r.hj, &r.tj, active, (n, nb), i)[j]
        });
        let (d, y) = delassus(&rows, &r.mass, at)?;
        let mut b = vec![0.0; size];
        system.joint_rates(t1, impact.q, vt, &mut b[..nb]);
        for (c, &a) in active.iter().enumerate() {
            b[nb + 2 * c] = self.normal_row(system, impact, r, a, report);
            b[nb + 2 * c + 1] = dot(&r.tj[a * n..(a + 1) * n], vt) + r.trates1[a];
        }
        let mu: Vec<f64> = active.iter().map(|&a| self.mu[a]).collect();
        let sol = solve_joint_friction_at(&d, &b, nb, &mu, &self.lcp, at, 0)?;
        apply_impulse(&y, &sol.z, v, at)?;
        report.joint_impulse.copy_from_slice(&sol.z[..nb]);
        for (c, &a) in active.iter().enumerate() {
            let (p, pt) = (sol.z[nb + 2 * c], sol.z[nb + 2 * c + 1]);
            report.base.impulse[a] = p;
            report.base.tangent_impulse[a] = pt;
            if p != 0.0 {
                let row = &r.hj[a * n..(a + 1) * n];
                *work_contact += p * 0.5 * (dot(row, vt) + dot(row, v));
            }
            if pt != 0.0 {
                let row = &r.tj[a * n..(a + 1) * n];
                let (before, after) = (pt * dot(row, vt), pt * dot(row, v));
                let split =
                    friction::split_tangential_work(0.5 * (before + after), 0.5, before, after);
                *work_friction += split.friction;
                *work_contact += split.contact;
            }
        }
        report.base.lcp = LcpStats {
            size: active.len(),
            iterations: sol.iterations,
            error: sol.error,
        };
        Ok(())
    }

    /// The end of the step: the applied forces and the works, the energy, the gaps, local
    /// velocities and joint residuals of the report; the end kept as the next step's start,
    /// and the state updated.
    #[allow(clippy::too_many_arguments)]
    fn finish<S: JointedSystem + ?Sized>(
        &mut self,
        system: &S,
        state: &mut NonlinearState,
        start: NsAlphaMemory,
        smooth: SmoothStage,
        q: Vec<f64>,
        velocity: VelocityStage,
        report: &mut NsAlphaStepReport,
        at: StepAt,
    ) -> Result<(), NonlinearStepError> {
        let (n, nb, t1) = (self.n, self.nb, at.t);
        let VelocityStage {
            v,
            rows,
            work_contact,
            work_friction,
        } = velocity;
        let mut applied = vec![0.0; n];
        system.applied_forces(t1, &q, &v, &mut applied);
        at.check_at(&applied, "the applied forces f(t, q, v)", &q, &v)?;
        let work_ext: f64 = (0..n)
            .map(|i| 0.5 * (start.applied[i] + applied[i]) * (q[i] - start.q[i]))
            .sum();
        let base = &mut report.base;
        base.kinetic = 0.5 * rows.mass.quadratic(&v);
        base.potential = system.potential(t1, &q);
        let energy = base.energy();
        if !energy.is_finite() {
            return Err(at.not_finite("the energy", energy));
        }
        base.work_ext = work_ext;
        base.work_contact = work_contact;
        base.work_friction = work_friction;
        base.energy_error = (energy - start.energy) - work_ext - work_contact - work_friction;
        base.newton_iterations = smooth.iterations;
        report.newton_matrices = smooth.matrices;
        system.gaps(t1, &q, &mut base.gap);
        at.check(&base.gap, "a gap g(q, t)")?;
        for (a, u) in base.local_velocity.iter_mut().enumerate() {
            *u = dot(&rows.hj[a * n..(a + 1) * n], &v) + rows.rates1[a];
        }
        if self.friction {
            for (a, u) in base.tangent_velocity.iter_mut().enumerate() {
                *u = dot(&rows.tj[a * n..(a + 1) * n], &v) + rows.trates1[a];
            }
        }
        report.penetration = base.gap.iter().fold(0.0f64, |p, &x| p.max(-x));
        let mut gb = vec![0.0; nb];
        system.joint_values(t1, &q, &mut gb);
        report.position_residual = amax(&gb);
        let mut jr = vec![0.0; nb];
        system.joint_rates(t1, &q, &v, &mut jr);
        report.velocity_residual = amax(&jr);
        report.lambda.copy_from_slice(&smooth.lambda);
        report.joint_rank = smooth.deficient.then(|| {
            let mut g = vec![0.0; nb * n];
            system.joint_jacobian(t1, &q, &mut g);
            numerical_rank(&g, nb, n)
        });

        self.last = Some(NsAlphaMemory {
            step: at.step,
            t: t1,
            q: q.clone(),
            v: v.clone(),
            a: smooth.a1,
            acc: smooth.acc,
            lambda: smooth.lambda,
            applied,
            energy,
            matrix_at: self.kept.as_ref().map(|k| k.at.clone()),
            before: Some((start.acc, start.lambda)),
            joint_rank: report.joint_rank.filter(|&r| r < nb),
        });
        state.q.copy_from_slice(&q);
        state.v.copy_from_slice(&v);
        state.t = t1;
        state.step = at.step;
        Ok(())
    }
}

/// The smooth stage's residual r = (M q̈ + Gᵀλ − F, G q̈ + κ) at the iterate, and its size
/// (module documentation): the dynamics rows relative to s = max_i (Σ_j |M_ij q̈_j| +
/// Σ_j |G_ji λ_j| + |F_i|), the joint rows as the force |r_j| ‖M‖∞ / ‖G_j‖∞ relative to s. M
/// and G are read through their nonzeros.
fn smooth_residual(
    x: &SmoothStage,
    mass: &Triplets,
    gj: &Triplets,
    f: &[f64],
    kappa: &[f64],
) -> (Vec<f64>, f64) {
    let (n, nb) = (f.len(), kappa.len());
    let mut r = vec![0.0; n + nb];
    // Per dynamics row: Σ_j |M_ij q̈_j| + Σ_j |G_ji λ_j|, and Σ_j |M_ij|; per joint ‖G_j‖∞.
    let (mut terms, mut mass_rows, mut g_rows) = (vec![0.0; n], vec![0.0; n], vec![0.0f64; nb]);
    for &(i, j, m) in mass.entries() {
        r[i] += m * x.acc[j];
        terms[i] += (m * x.acc[j]).abs();
        mass_rows[i] += m.abs();
    }
    for &(k, i, g) in gj.entries() {
        r[i] += g * x.lambda[k];
        terms[i] += (g * x.lambda[k]).abs();
        r[n + k] += g * x.acc[i];
        g_rows[k] = g_rows[k].max(g.abs());
    }
    let (mut r1, mut s1) = (0.0f64, 0.0f64);
    for i in 0..n {
        r[i] -= f[i];
        r1 = r1.max(r[i].abs());
        s1 = s1.max(terms[i] + f[i].abs());
    }
    let mass_norm = mass_rows.iter().fold(0.0f64, |a, &b| a.max(b));
    let mut r2 = 0.0f64;
    for j in 0..nb {
        r[n + j] += kappa[j];
        r2 = r2.max(r[n + j].abs() * mass_norm / g_rows[j].max(f64::MIN_POSITIVE));
    }
    let rel = |r: f64, s: f64| if r == 0.0 { 0.0 } else { r / s };
    (r, rel(r1, s1).max(rel(r2, s1)))
}

/// Solves Newton's saddle-point system S x = r of the smooth stage (S given by its entries)
/// with [`factor_saddle`]: x, and whether S was singular with the joints rank-deficient (x the
/// minimum-norm least-squares solution); None when S is singular otherwise.
fn solve_saddle(
    s: &Triplets,
    mut r: DVector<f64>,
    joints: &Triplets,
    band: Option<&BandOrder>,
) -> Option<(DVector<f64>, bool)> {
    let factor = factor_saddle(s, joints, band, 0)?;
    factor.solve_mut(&mut r).then(|| (r, factor.deficient()))
}

/// Factorises Newton's saddle-point matrix S of the smooth stage (given by its entries): LU
/// when S is regular (the band LU in the order `band` for a large model, assembled from the
/// entries, [`crate::soi2::banded`]), the SVD of [`NewtonFactor`] for the minimum-norm
/// least-squares solve when S is singular to working precision because the nb×n joint
/// Jacobian `joints` has lost rank; None when S is singular otherwise.
///
/// "Singular to working precision" is read from LU's pivots, min |u_kk| ≤ size · ε · max
/// |u_kk|, for the dense LU as for the band LU. The dense LU's own test (each pivot against
/// its column) is not enough: off the manifold Bricard's redundant joints give G(q̃) a
/// smallest singular value of 1e-9 σ_max (not 0), S's pivots span 1e-17 and pass that test,
/// and the regular solve puts a component of the size of the residual over σ_min² along the
/// near-null direction of Gᵀ into λ (3e7 instead of 21 at h = 2e-3, until the run failed).
/// A dense S with such pivots whose joints keep their rank stays with its LU, as before.
///
/// `redundant` > 0 is the joints' rank deficit at the start of the step, where the positions
/// are on the manifold and the rank is sharp: S is then solved by its SVD at rank at most
/// size − `redundant` whatever its pivots say. Off the manifold the near-null singular values
/// of G(q̃) only approach zero, and a single step whose S passed the pivot test put λ's
/// near-null component at 2.5e6 for the rest of the run (the minimum-norm increments never
/// remove it): Bricard at h = 2e-3, t = 0.26 s.
fn factor_saddle(
    s: &Triplets,
    joints: &Triplets,
    band: Option<&BandOrder>,
    redundant: usize,
) -> Option<NewtonFactor> {
    let (size, nb) = (s.rows(), joints.rows());
    let n = size - nb;
    let dense = || DMatrix::from_row_slice(size, size, &s.to_dense());
    if redundant > 0 {
        return Some(NewtonFactor::least_squares_of_rank(
            &dense(),
            size - redundant.min(nb),
        ));
    }
    let banded = band
        .filter(|b| b.order.len() == size)
        .and_then(|b| BandLu::factor_entries(b, s.entries().iter().copied()));
    // The LU, whether its pivots show a regular matrix, and what stands when they do not and
    // the joints keep their rank (the dense LU that passed its column test; no band LU).
    let (regular, fallback) = match banded {
        Some(lu) => {
            let (lo, hi) = lu.pivot_range();
            let regular = lo > size as f64 * f64::EPSILON * hi;
            (regular.then_some(NewtonFactor::Banded(lu)), None)
        }
        None => match lu_factor(dense()) {
            Some(lu) => {
                let (lo, hi) = pivot_range(&lu);
                let lu = NewtonFactor::Regular(lu);
                if lo > size as f64 * f64::EPSILON * hi {
                    (Some(lu), None)
                } else {
                    (None, Some(lu))
                }
            }
            None => (None, None),
        },
    };
    if regular.is_some() {
        return regular;
    }
    // Singular: the minimum-norm solve when the joints have lost rank. S's multiplier block
    // goes like G M⁻¹ Gᵀ, so S is singular to working precision once σ_min(G)² ≤ size · ε ·
    // σ_max(G)²: the joints count as rank-deficient from that ratio (off the manifold, at q̃,
    // Bricard's G has σ_min = 1e-10 to 1e-9 σ_max, not 0).
    let sv = crate::dense::singular_values(DMatrix::from_row_slice(nb, n, &joints.to_dense()))?;
    let lost = (size as f64 * f64::EPSILON).sqrt() * sv.max();
    if nb == 0 || !(sv.min() <= lost || nb > n) {
        return fallback;
    }
    let factor = NewtonFactor::least_squares(&dense());
    if factor.deficient() {
        Some(factor)
    } else {
        fallback
    }
}

/// The rows C = [G; H_I] (joints, then the contacts of `active`), row-major.
/// The last position correction `dq` is at the round-off of the positions `q`: Newton has
/// nothing more to gain.
fn at_round_off(dq: &[f64], q: &[f64]) -> bool {
    amax(dq) <= 4.0 * f64::EPSILON * amax(q)
}

fn constraint_rows(g: &[f64], h: &[f64], active: &[usize], n: usize) -> Vec<f64> {
    let mut rows = g.to_vec();
    for &a in active {
        rows.extend_from_slice(&h[a * n..(a + 1) * n]);
    }
    rows
}

/// What a run of the scheme measured over all its steps; its fields are those of
/// `summary.json`.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct NsAlphaRunStats {
    /// Steps, energies, impacts, LCP (velocity stage) and Newton (smooth stage) figures, works,
    /// as for the nonlinear Moreau–Jean scheme.
    #[serde(flatten)]
    pub base: NonlinearRunStats,
    /// max_k ‖g(q_k, t_k)‖∞ over the joints.
    pub max_position_residual: f64,
    /// max_k ‖G v_k + g_t‖∞ over the joints.
    pub max_velocity_residual: f64,
    /// max_k max(0, −min_α g_α(q_k, t_k)).
    pub max_penetration: f64,
    /// Largest number of Newton iterates of a position stage.
    pub position_iterations_max: usize,
    /// Steps whose smooth stage met a singular Newton matrix because the joints had lost
    /// rank (minimum-norm increment), as SOI2's field of that name.
    #[serde(default)]
    pub rank_deficient_steps: u64,
    /// The smallest numerical rank of G(q_{k+1}) over those steps (`None` when there were
    /// none).
    #[serde(default)]
    pub smallest_rank: Option<usize>,
    /// Newton matrices of the smooth stage formed and factorised over the run (as SOI2's
    /// field of that name: the iterations under full Newton, fewer under simplified Newton).
    #[serde(default)]
    pub newton_jacobians_total: u64,
}

/// Summary of a run of the scheme (`summary.json`): the model's sizes, the step and the
/// coefficients, then what the run measured ([`NsAlphaRunStats`], its fields flat).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct NsAlphaSummary {
    /// Generalized coordinates.
    pub dofs: usize,
    /// Contacts.
    pub contacts: usize,
    /// Joints.
    pub joints: usize,
    /// Step size.
    pub h: f64,
    /// α_m.
    pub alpha_m: f64,
    /// α_f.
    pub alpha_f: f64,
    /// β.
    pub beta: f64,
    /// γ.
    pub gamma: f64,
    /// What the run measured.
    #[serde(flatten)]
    pub stats: NsAlphaRunStats,
}

/// Column names of a run of the scheme: `kinetic, potential, energy, work_ext, work_contact,
/// work_friction, energy_error, work_ext_total, work_contact_total`, with friction
/// `work_friction_total`, then `newton_iterations, position_iterations`, `gap_α, u_α, p_α` per
/// contact (with friction also `pt_α, ut_α`: tangential impulse and velocity, as under the
/// nonlinear Moreau–Jean scheme), `lambda_j` per joint, `position_residual,
/// velocity_residual`, then `q_j, v_j` per probe. A system without friction has exactly the
/// frictionless columns.
pub fn ns_alpha_columns(
    contacts: usize,
    friction: bool,
    joints: usize,
    probes: &[usize],
) -> Columns {
    let mut names: Vec<String> = [
        "kinetic",
        "potential",
        "energy",
        "work_ext",
        "work_contact",
        "work_friction",
        "energy_error",
        "work_ext_total",
        "work_contact_total",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    if friction {
        names.push("work_friction_total".into());
    }
    names.extend(["newton_iterations".into(), "position_iterations".into()]);
    contact_columns(contacts, friction, &mut names);
    names.extend((0..joints).map(|j| format!("lambda_{j}")));
    names.extend(["position_residual".into(), "velocity_residual".into()]);
    probe_columns(probes, &mut names);
    Columns::new(names)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pentadiagonal, diagonally dominant M of n unknowns (not symmetric), as its entries.
    fn banded(n: usize) -> Triplets {
        let mut m = Triplets::new(n, n);
        for i in 0..n {
            for j in i.saturating_sub(2)..(i + 3).min(n) {
                let v = if i == j {
                    5.0 + (i % 7) as f64
                } else {
                    ((i * 3 + j * 5) % 11) as f64 / 11.0 - 0.5
                };
                m.push(i, j, v);
            }
        }
        m
    }

    /// The mass factor takes the band LU for a long banded M and the dense LU for a small one;
    /// both solve M X = B to round-off against nalgebra's dense LU, and a singular M is refused
    /// on either path.
    #[test]
    fn the_mass_factor_is_banded_when_it_pays_and_solves_as_the_dense_lu() {
        for (n, band) in [(10, false), (200, true)] {
            let m = banded(n);
            let factor = MassFactor::new(&m).expect("regular");
            assert_eq!(matches!(factor, MassFactor::Band(_)), band, "n = {n}");
            let b = DMatrix::from_fn(n, 3, |i, j| ((i + 2 * j) % 5) as f64 - 2.0);
            let x = factor.solve(&b).expect("a solve");
            let dense = mat(n, n, &m.to_dense());
            let reference = dense.clone().lu().solve(&b).expect("regular");
            let error = (&x - &reference).amax() / reference.amax();
            assert!(error <= 1e-14, "n = {n}: {error:e}");
            assert!((&dense * &x - &b).amax() <= 1e-13 * b.amax());
            // Row 3 made a copy of row 2: singular.
            let mut singular = Triplets::new(n, n);
            for &(i, j, v) in m.entries() {
                if i != 3 {
                    singular.push(i, j, v);
                }
                if i == 2 {
                    singular.push(3, j, v);
                }
            }
            assert!(MassFactor::new(&singular).is_none(), "n = {n}: singular");
        }
    }
}
