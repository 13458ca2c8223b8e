//! Moreau–Jean time-stepping of rigid bodies: Siconos' `MoreauJeanOSI` on `NewtonEulerDS`
//! (V. Acary, B. Brogliato, *Numerical Methods for Nonsmooth Dynamical Systems*, Springer, 2008,
//! doi:10.1007/978-3-540-75392-6, ch. 10; M. Jean, *The non-smooth contact dynamics method*,
//! Comput. Methods Appl. Mech. Engrg. 177 (1999) 235–257, doi:10.1016/S0045-7825(98)00383-1), with
//! the three-dimensional friction problem of [`crate::friction::fc3d`] per step.
//!
//! Per free body, with mass m, principal inertia I = diag(I_1, I_2, I_3), position x, unit
//! quaternion q, velocity v (world) and angular velocity Ω (body frame, [`super::body`]), the
//! Newton–Euler equations m v̇ = m g, I Ω̇ + Ω × IΩ = 0 (gravity the only applied load; the
//! gyroscopic term Ω × IΩ) and q̇ = T(q)Ω = ½ q ⊗ (0, Ω) are discretised from t_k to
//! t_{k+1} = t_k + h with θ ∈ [0, 1], z_{k+θ} = (1 − θ) z_k + θ z_{k+1}:
//!
//! ```text
//! m (v_{k+1} − v_k) = h m g + Σ_c G_{c,v}ᵀ P_c                                       (1a)
//! I (Ω_{k+1} − Ω_k) + h Ω_{k+θ} × I Ω_{k+θ} = Σ_c G_{c,Ω}ᵀ P_c                          (1b)
//! x_{k+1} = x_k + h v_{k+θ},     q_{k+1} = q_k ⊗ exp(h Ω_{k+θ})                       (1c)
//! ```
//!
//! where P_c = (P_n, P_t1, P_t2) is the impulse of contact c in its frame (n, t_1, t_2) and
//! G_c the contact's velocity Jacobian at the poses of t_k: for a contact between bodies 0 and
//! 1 with witness points p_0, p_1, the local velocity is U_c = Σ_s σ_s G_{c,s} (v_s, Ω_s) with
//! σ_0 = −1, σ_1 = +1, rows d ∈ {n, t_1, t_2}: `G_{c,s} d-row = (dᵀ, (R_sᵀ(r_s × d))ᵀ)`,
//! r_s = p_s − x_s.
//!
//! The gyroscopic term is evaluated at Ω_{k+θ} (Siconos takes (1 − θ)F_k + θF_{k+1}): then for
//! θ = ½, (1b) is the implicit midpoint rule on Euler's equations, Ω_{k+½}·(Ω_{k+½} × IΩ_{k+½}) =
//! 0, and the energy ledger below closes exactly; the midpoint rule also keeps the quadratic
//! invariants ΩᵀIΩ and ‖IΩ‖ of the torque-free body.
//!
//! **Quaternion.** (1c) is the exponential-map (Lie group) update of Brüls & Cardona
//! (O. Brüls, A. Cardona, *On the use of Lie group time integrators in multibody dynamics*,
//! J. Comput. Nonlinear Dynam. 5(3) 031002, 2010, doi:10.1115/1.4001370): exp(φ) = (cos ½‖φ‖,
//! sin ½‖φ‖ φ/‖φ‖) is a unit quaternion, so q stays on the unit sphere by construction; the
//! product is divided by its norm once per step, which only removes the accumulated round-off
//! (the quaternion is unit to 1e-15 over any number of steps). It is first-order consistent with
//! q̇ = T(q)Ω.
//!
//! **Newton.** (1b) is nonlinear in Ω_{k+1}; as `MoreauJeanOSI` does, each Newton iterate Ω^i
//! (from Ω^0 = Ω_k) solves the linearised one-step problem:
//!
//! ```text
//! J^i = I + hθ (S(Ω_θ^i) I − S(I Ω_θ^i)),   S(a) b = a × b
//! Ω_free = Ω^i − (J^i)⁻¹ (I(Ω^i − Ω_k) + h Ω_θ^i × IΩ_θ^i),   v_free = v_k + h g
//! W = Σ_s G_{c,s} diag(m⁻¹ 1, (J^i)⁻¹) G_{d,s}ᵀ     (Delassus operator, 3×3 blocks)
//! u = W P + q_c,   q_c = G_c (v_free, Ω_free) + (e_c U_{n,k}, 0, 0)                     (FC3D)
//! (v, Ω)^{i+1} = (v_free, Ω_free) + diag(m⁻¹ 1, (J^i)⁻¹) Σ_c G_cᵀ P_c
//! ```
//!
//! solved by [`crate::friction::solve_fc3d`] with Coulomb's law on the cone of μ_c (De Saxcé's
//! formulation) and Newton's impact law in the normal rows (u_n = U_{n,k+1} + e U_{n,k}).
//! Newton stops when the residual of (1b) at the new iterate is ≤ `newton_tolerance` times the
//! size of its terms (‖IΩ_k‖ + ‖IΩ_{k+1}‖ + h‖Ω_θ × IΩ_θ‖ + ‖Σ G_Ωᵀ P‖, max norms); (1a) is linear and holds after the first iterate.
//!
//! **Index set** (Siconos' predicted gap, `MoreauJeanOSI::addInteractionInIndexSet`): the
//! detector reports every contact point of gap g_c ≤ `margin` at the poses of t_k; contact c
//! enters the index set when its predicted gap g_c + γ h U_{n,k} ≤ `margin`
//! (U_{n,k} = G_c v_k, γ = `gamma`, default ½), or ≤ `activation_gap` when that is set. With
//! the margin, no contact penetrates, but bodies come to rest up to the margin apart (on the
//! 1 000-sphere pour the loaded contacts stand 4.85 mm apart with a 5 mm margin); Siconos
//! compares with 0 (`activation_gap` = 0: the margin only finds the candidates), and bodies
//! then touch, an impact leaving up to ½ h |U_n| of penetration that a velocity-level scheme
//! does not correct (docs/rigid_benchmark.md, Round 20).
//!
//! **Warm start** (`warm_start`, default on). Each FC3D solve starts from the best guess at hand
//! instead of P = 0, as Siconos' `LinearOSNS::preCompute` does with `keepLambdaAndYState` (its
//! default: each interaction's last λ is the next problem's start): a Newton iterate after the first starts from the previous iterate's impulses (same
//! index set), and the first from the last step's impulse of the same contact, recognised by its
//! two bodies and the features the detector says the point joins ([`ContactPoint::features`]); that
//! impulse is kept in world coordinates, P = P_n n + P_t1 t_1 + P_t2 t_2, and read in the new frame
//! as (P·n', P·t_1', P·t_2'), so a contact whose normal turned starts from the same vector (a pair
//! found in the other order starts from −P). A new contact starts from 0. The problem, its tolerance
//! and hence the bound on the error are those of a cold start; the last step's impulses are part of
//! the state a checkpoint keeps, so a resumed run stays bit for bit.
//!
//! **Unsolved friction problems.** Coulomb friction is not monotone, and no FC3D solver is
//! known to converge on every problem; on a formed pile of 2 187 contacts (the 1 000-sphere
//! pour's step 569, docs/rigid_benchmark.md) every stage of `auto` spends its budget above the
//! tolerance. By default such a step fails. With `accept_error` = ε the step goes on with the
//! solver's iterate of smallest error when that error is ≤ ε, as Siconos' time stepping goes
//! on with the impulses of a solver that did not converge and MuJoCo's solver stops after its
//! iteration budget whatever its residual; but here it is counted: the step's
//! [`StepReport::friction_accepted`] and the run's statistics say how many solves were accepted
//! and their largest error. The ledger below still closes (it holds for any impulse the
//! update applies); what is violated, to the error's order, is Coulomb's law.
//!
//! **Energy ledger.** `kinetic` K = Σ ½ m‖v‖² + ½ ΩᵀIΩ, `potential` V = −Σ m g·x, `work_ext` = 0
//! (no applied load besides gravity, which is in V), `work_contact` = Σ_c P_n U_{n,k+θ},
//! `work_friction` = Σ_c (P_t1 U_{t1,k+θ} + P_t2 U_{t2,k+θ}), with U_{k+θ} = G_c (v, Ω)_{k+θ},
//! except on a step where a contact's tangential velocity reverses (P_t · U_{t,k} > 0): there its
//! friction work is θ P_t · U_{t,k+1} (≤ 0 by Coulomb's law on U_{k+1}) and the rest of its
//! tangential work joins `work_contact` ([`crate::friction::split_tangential_work`]);
//! `energy_error` = ΔK + ΔV − work_ext − work_contact − work_friction. For θ = ½, multiply (1a)
//! by v_{k+½} and (1b) by Ω_{k+½}: since ½‖a‖² − ½‖b‖² = ((a + b)/2)·(a − b),
//!
//! ```text
//! ΔK = h m g·v_{k+½} − Ω_{k+½}·(Ω_{k+½} × IΩ_{k+½}) h + Σ_c P_c·G_c(v, Ω)_{k+½}
//!    = −ΔV + 0 + work_contact + work_friction           (ΔV = −m g·(x_{k+1} − x_k) = −h m g·v_{k+½})
//! ```
//!
//! so `energy_error` is zero up to round-off and the Newton residual. For θ ≠ ½ it is the
//! scheme's numerical dissipation (½ − θ)‖Δ(v, Ω)‖²_M up to the gyroscopic term. At an impact
//! with e ≤ 1 and θ = ½, U_{n,k+1} = −e U_{n,k} when P_n > 0, so P_n U_{n,k+½} =
//! ½(1 − e) U_{n,k} P_n ≤ 0: an impact never creates energy.

use super::body::{BodyState, Pose};
use super::detector::{ContactDetector, ContactPoint, DetectError};
use super::joint::{InverseMass, JointRow, add_joint_impulse, joint_operator, project};
use super::scene::RigidScene;
use crate::friction::{
    BlockCsr, Fc3dError, Fc3dOptions, Fc3dProblem, Fc3dStall, solve_fc3d_from,
    split_tangential_work,
};
use nalgebra::{DMatrix, DVector, Matrix3, Quaternion, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use thiserror::Error;

/// The phases of a step, in the order Siconos' `TimeStepping` names them: contact detection,
/// assembly of the one-step problem (index set, Delassus operator, free local velocity), its
/// solution (FC3D), and the update (free velocities, Newton iterates, (1c), the joints).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StepPhase {
    /// Collision detection at the current poses.
    Detection,
    /// Index set and the one-step problem's W and q.
    Assembly,
    /// The FC3D solve.
    Solve,
    /// Free state, velocity and pose updates.
    Update,
}

/// Told when each phase of a step starts (a benchmark times them; the core has no clock).
pub trait StepPhases {
    /// Phase `phase` starts now.
    fn enter(&mut self, phase: StepPhase);

    /// The one-step friction problem about to be solved and the start its solver is given (the
    /// warm start, or zeros): a benchmark may keep it as a problem file. Nothing by default.
    fn problem(&mut self, _problem: &Fc3dProblem, _start: &[f64]) {}
}

/// No one listening.
impl StepPhases for () {
    fn enter(&mut self, _phase: StepPhase) {}
}

/// The Gauss–Seidel sweeps `auto` gives a rigid step's friction problem before its
/// proximal-point stage (`Fc3dOptions::auto_sweeps`; 100 for a lone problem). On the 1 000-sphere
/// benchmark (docs/rigid_benchmark.md), 223 of the first 300 steps need 100–1 000 sweeps at 1e-6
/// and none more; with 100, those steps went on to the proximal point method, whose Newton
/// iterations on 3 000–4 800 unknowns made the step 1.9× slower than Gauss–Seidel alone. Since
/// Round 7 the sweeps are accelerated (Anderson, falling back to plain sweeps where that stalls):
/// 7 of the first 400 steps need more than 1 000 of them. Once the pile has formed (steps
/// 385–614, 1 900–2 200 contacts) half the steps did, and the proximal point then failed on most
/// of them at 1–7 s a step before Gauss–Seidel finished (Round 11); with the fallback
/// over-relaxed ([`RELAXATION`]) the sweeps finish within 5 000 on the dumped steps (1 050–2 125
/// from the warm start, where plain ones need 2 331–7 520), at about 1 ms a sweep: what the
/// proximal attempt cost.
pub const AUTO_SWEEPS: usize = 5000;

/// The over-relaxation ω of the plain Gauss–Seidel sweeps that a rigid step's `auto` falls back
/// to when the accelerated ones stall (`Fc3dOptions::relaxation`; 1 for a lone problem). On the
/// 1 000-sphere pile (docs/rigid_benchmark.md, Round 11) plain sweeps from the warm start needed
/// 1.9–3.1× fewer sweeps at 1.5 than at 1 on five dumped steps of 1 800–2 220 contacts; 1.6 was
/// faster still on three of them, but 1.7 stalled on one and 1.85 on all: 1.5 keeps a margin.
pub const RELAXATION: f64 = 1.5;

/// The stagnation window of a rigid step's Gauss–Seidel sweeps when the step accepts errors up
/// to `accept_error` ([`RigidMoreauJeanParams::stall_sweeps`], `Fc3dOptions::stall`; none for a
/// lone problem): sweeps within that bound stop once 1 000 in a row have not cut the smallest
/// error by 10 %. On the formed pile of the 1 000-sphere benchmark (docs/rigid_benchmark.md,
/// Round 18) the sweeps of some steps cycle at a fixed error for their whole budget (step 569:
/// 1.399·10⁻⁵ from sweep 1 000 to sweep 50 000): with the window that step's `auto` took 2.7 s
/// instead of 6.6 s (and 2.3 s with 500 sweeps), and the four dumped steps it converges on
/// the same or faster, while a window of 200 sweeps made one of them fail.
pub const STALL_SWEEPS: usize = 1000;

/// Parameters of the scheme.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidMoreauJeanParams {
    /// θ ∈ [0, 1] of (1); ½ keeps the energy ledger exact.
    pub theta: f64,
    /// γ ≥ 0 of the predicted gap g + γ h U_n (Siconos' default ½).
    pub gamma: f64,
    /// The predicted gap at or below which a contact enters the index set; `None` (default):
    /// the scene's margin (module documentation, *Index set*).
    pub activation_gap: Option<f64>,
    /// Relative residual at which Newton stops, > 0 (default 1e-14: quadratic convergence
    /// reaches it one iterate after 1e-7, and the ledger then closes at round-off).
    pub newton_tolerance: f64,
    /// Newton iterates per step before the step fails (default 50).
    pub newton_max_iterations: usize,
    /// The FC3D solver's settings.
    pub fc3d: Fc3dOptions,
    /// max|φ| of the joints (m, or dimensionless for an axis row) at which the projection after
    /// a step stops, > 0 (default 1e-12).
    pub projection_tolerance: f64,
    /// Projection iterates per step at most (default 20; quadratic convergence needs 2–3).
    pub projection_max_iterations: usize,
    /// Start each FC3D solve from the last impulses of the same contacts (module
    /// documentation) rather than from 0. Default true; false only to measure what it saves.
    pub warm_start: bool,
    /// The largest FC3D error a step accepts when its solver spends its budget above
    /// `fc3d.tolerance` (module documentation, *Unsolved friction problems*); `None` (default):
    /// such a step fails.
    pub accept_error: Option<f64>,
    /// With `accept_error`, the FC3D solver's sweeps stop once this many in a row have not cut
    /// their smallest error by 10 % and that error is within `accept_error` (`Fc3dOptions::stall`,
    /// which this sets for each solve). Default [`STALL_SWEEPS`]; `None`: they spend the budget.
    pub stall_sweeps: Option<usize>,
}

impl Default for RigidMoreauJeanParams {
    fn default() -> Self {
        Self {
            theta: 0.5,
            gamma: 0.5,
            activation_gap: None,
            newton_tolerance: 1e-14,
            newton_max_iterations: 50,
            fc3d: Fc3dOptions {
                tolerance: 1e-12,
                auto_sweeps: AUTO_SWEEPS,
                relaxation: RELAXATION,
                ..Fc3dOptions::default()
            },
            projection_tolerance: 1e-12,
            projection_max_iterations: 20,
            warm_start: true,
            accept_error: None,
            stall_sweeps: Some(STALL_SWEEPS),
        }
    }
}

/// Why a step failed, with its step and time.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum RigidStepError {
    /// Contact detection failed.
    #[error("step {step} (t = {t}): contact detection: {source}")]
    Detect {
        /// Step.
        step: u64,
        /// Time t_k.
        t: f64,
        /// Why.
        source: DetectError,
    },
    /// The friction problem was not solved.
    #[error("step {step} (t = {t}): friction problem of {contacts} contacts: {source}")]
    Friction {
        /// Step.
        step: u64,
        /// Time t_k.
        t: f64,
        /// Contacts in the index set.
        contacts: usize,
        /// Why.
        source: Fc3dError,
    },
    /// Newton did not converge on (1b).
    #[error(
        "step {step} (t = {t}): Newton did not converge in {iterations} iterates (relative residual {residual:e})"
    )]
    Newton {
        /// Step.
        step: u64,
        /// Time t_k.
        t: f64,
        /// Iterates done.
        iterations: usize,
        /// Last relative residual.
        residual: f64,
    },
    /// The rotational iteration matrix J of a body is singular (hθ‖Ω‖ far too large).
    #[error("step {step} (t = {t}): the iteration matrix of body {body} is singular")]
    SingularIteration {
        /// Step.
        step: u64,
        /// Time t_k.
        t: f64,
        /// The body.
        body: usize,
    },
    /// A state value became NaN or infinite.
    #[error("step {step} (t = {t}): the state of body {body} is not finite")]
    NotFinite {
        /// Step.
        step: u64,
        /// Time t_{k+1}.
        t: f64,
        /// The body.
        body: usize,
    },
}

/// What one step did, for its record and the run's statistics.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepReport {
    /// Contacts in the index set.
    pub contacts: usize,
    /// Σ_c P_n U_{n,k+θ}.
    pub work_contact: f64,
    /// Σ_c P_t·U_{t,k+θ}.
    pub work_friction: f64,
    /// Newton iterates.
    pub newton_iterations: usize,
    /// FC3D iterations, summed over the iterates.
    pub friction_iterations: usize,
    /// The FC3D error of the last solve (0 without contact).
    pub friction_error: f64,
    /// Whether a solve of the step ended above the FC3D tolerance and its best iterate was
    /// accepted ([`RigidMoreauJeanParams::accept_error`]).
    pub friction_accepted: bool,
    /// Σ_j Λ_j (J (v, Ω)_{k+θ})_j: the work of the joints' impulses (zero for exact joints;
    /// here the scheme's O(h²) per step, see the module documentation).
    pub work_joint: f64,
    /// max|φ| of the joints after the step's projection (0 without joints).
    pub position_residual: f64,
}

/// A step's friction solve ([`RigidMoreauJean::solve_friction`]): the impulses, the FC3D
/// iterations spent, the error, and whether the impulses were accepted above the tolerance.
struct FrictionSolve {
    impulse: Vec<f64>,
    iterations: usize,
    error: f64,
    accepted: bool,
}

/// One active contact: its bodies' Jacobian blocks and its start velocity.
#[derive(Debug, Clone)]
struct ActiveContact {
    /// Per side: the body and its signed 3×6 block σ_s G_{c,s} (rows n, t1, t2; columns v, Ω),
    /// `None` for a fixed body.
    sides: [Option<(usize, [[f64; 6]; 3])>; 2],
    /// U_k = G_c (v, Ω)_k.
    u_start: [f64; 3],
    restitution: f64,
    friction: f64,
}

/// The impulse of one contact of a step's index set, kept to warm-start the next step's friction
/// problem (module documentation): the key that recognises the contact, and its impulse.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ContactImpulse {
    /// The two bodies, in the detector's order.
    pub bodies: [usize; 2],
    /// The features of [`ContactPoint::features`].
    pub features: [u32; 2],
    /// The impulse body 1 received, in world coordinates: P_n n + P_t1 t_1 + P_t2 t_2.
    pub impulse: [f64; 3],
}

/// Buffers a step reuses (never in a checkpoint: rebuilt from the state), and the last step's
/// impulses per contact, which are state ([`Self::previous_impulses`]).
#[derive(Debug, Clone, Default)]
pub struct RigidScratch {
    /// The contact points at the current poses, when `found_valid`.
    pub found: Vec<ContactPoint>,
    found_valid: bool,
    poses: Vec<Pose>,
    active: Vec<ActiveContact>,
    /// The contact points of the index set of the last step, in the order of `active`.
    active_points: Vec<ContactPoint>,
    /// The last step's impulses P_{k+1}, (P_n, P_t1, P_t2) per contact of `active_points`.
    impulse: Vec<f64>,
    /// The last step's impulses per contact, the warm start of the next step.
    previous: Vec<ContactImpulse>,
}

impl RigidScratch {
    /// A scratch whose next step starts from the impulses `previous` (a run resumed from a
    /// checkpoint, which keeps them).
    pub fn resumed(previous: Vec<ContactImpulse>) -> Self {
        Self {
            previous,
            ..Self::default()
        }
    }

    /// The last step's impulse of every contact of its index set (empty before the first step):
    /// what the next step's friction problem starts from, part of the state a checkpoint keeps.
    pub fn previous_impulses(&self) -> &[ContactImpulse] {
        &self.previous
    }

    /// The start of the friction problem of the index set (`active_points`): per point, the last
    /// step's impulse of the same contact (same bodies and features; a pair found in the other
    /// order gives −P) in the point's frame, or 0 for a contact that was not in the last index
    /// set; all 0 when `warm` is false.
    fn warm_start(&self, warm: bool) -> Vec<f64> {
        let points = &self.active_points;
        if !warm {
            return vec![0.0; 3 * points.len()];
        }
        let mut known: HashMap<([usize; 2], [u32; 2]), [f64; 3]> =
            HashMap::with_capacity(self.previous.len());
        for c in &self.previous {
            known.entry((c.bodies, c.features)).or_insert(c.impulse);
        }
        let mut start = Vec::with_capacity(3 * points.len());
        for point in points {
            let [b0, b1] = point.bodies;
            let [f0, f1] = point.features;
            let p = match known.get(&(point.bodies, point.features)) {
                Some(p) => *p,
                None => match known.get(&([b1, b0], [f1, f0])) {
                    Some(p) => [-p[0], -p[1], -p[2]],
                    None => [0.0; 3],
                },
            };
            let along = |d: [f64; 3]| p[0] * d[0] + p[1] * d[1] + p[2] * d[2];
            start.extend([
                along(point.normal),
                along(point.tangents[0]),
                along(point.tangents[1]),
            ]);
        }
        start
    }

    /// Keeps the step's impulses (per contact of `active_points`) for the next step.
    fn keep_impulses(&mut self) {
        self.previous.clear();
        for (point, p) in self.active_points.iter().zip(self.impulse.chunks_exact(3)) {
            let [n, t1, t2] = [point.normal, point.tangents[0], point.tangents[1]];
            let world = |i: usize| p[0] * n[i] + p[1] * t1[i] + p[2] * t2[i];
            self.previous.push(ContactImpulse {
                bodies: point.bodies,
                features: point.features,
                impulse: [world(0), world(1), world(2)],
            });
        }
    }

    /// Detects the contact points at the current poses (kept for the next step).
    pub fn detect(
        &mut self,
        scene: &RigidScene,
        state: &[BodyState],
        detector: &mut dyn ContactDetector,
    ) -> Result<&[ContactPoint], DetectError> {
        if !self.found_valid {
            self.poses.clear();
            self.poses.extend(state.iter().map(BodyState::pose));
            detector.detect(&self.poses, scene.margin, &mut self.found)?;
            self.found_valid = true;
        }
        Ok(&self.found)
    }

    /// max(0, −min gap) over the contact points at the current poses.
    pub fn max_penetration(&self) -> f64 {
        self.found.iter().map(|c| -c.gap).fold(0.0, f64::max)
    }

    /// The last step's index set: each contact point (found at the start of the step) with its
    /// impulse P_{k+1} = (P_n, P_t1, P_t2) in the frame (n, t_1, t_2) of the point. Empty before
    /// the first step and after a restore.
    pub fn active_impulses(&self) -> impl Iterator<Item = (&ContactPoint, [f64; 3])> {
        self.active_points
            .iter()
            .zip(self.impulse.chunks_exact(3))
            .map(|(point, p)| (point, [p[0], p[1], p[2]]))
    }
}

/// The scheme: its parameters and step.
#[derive(Debug, Clone, PartialEq)]
pub struct RigidMoreauJean {
    params: RigidMoreauJeanParams,
    h: f64,
}

type V3 = Vector3<f64>;

fn v3(a: [f64; 3]) -> V3 {
    V3::from(a)
}

fn skew(a: &V3) -> Matrix3<f64> {
    Matrix3::new(0.0, -a.z, a.y, a.z, 0.0, -a.x, -a.y, a.x, 0.0)
}

impl RigidMoreauJean {
    /// The scheme with step h > 0.
    pub fn new(params: RigidMoreauJeanParams, h: f64) -> Self {
        Self { params, h }
    }

    /// Its parameters.
    pub fn params(&self) -> &RigidMoreauJeanParams {
        &self.params
    }

    /// Step size h.
    pub fn h(&self) -> f64 {
        self.h
    }

    /// Kinetic energy Σ ½ m‖v‖² + ½ ΩᵀIΩ and potential −Σ m g·x of the free bodies.
    pub fn energies(scene: &RigidScene, state: &[BodyState]) -> (f64, f64) {
        let g = v3(scene.gravity);
        let mut kinetic = 0.0;
        let mut potential = 0.0;
        for (b, s) in scene.bodies.iter().zip(state) {
            if b.fixed {
                continue;
            }
            let v = v3(s.velocity);
            let w = v3(s.angular_velocity);
            kinetic += 0.5 * b.mass * v.norm_squared()
                + 0.5
                    * (b.inertia[0] * w.x * w.x
                        + b.inertia[1] * w.y * w.y
                        + b.inertia[2] * w.z * w.z);
            potential -= b.mass * g.dot(&v3(s.position));
        }
        (kinetic, potential)
    }

    /// Advances `state` from t_k (step k − 1 done) by one step (module documentation). The
    /// scratch's contact points are those of the current poses (detected here when the scratch
    /// has none) and, after the step, those of the new poses.
    pub fn step(
        &self,
        scene: &RigidScene,
        state: &mut [BodyState],
        detector: &mut dyn ContactDetector,
        scratch: &mut RigidScratch,
        step: u64,
        t: f64,
    ) -> Result<StepReport, RigidStepError> {
        self.step_in_phases(scene, state, detector, scratch, (step, t), &mut ())
    }

    /// [`Self::step`], telling `phases` when each phase of it starts (a benchmark's clock; the
    /// core keeps none).
    pub fn step_in_phases(
        &self,
        scene: &RigidScene,
        state: &mut [BodyState],
        detector: &mut dyn ContactDetector,
        scratch: &mut RigidScratch,
        (step, t): (u64, f64),
        phases: &mut dyn StepPhases,
    ) -> Result<StepReport, RigidStepError> {
        let h = self.h;
        phases.enter(StepPhase::Detection);
        scratch
            .detect(scene, state, detector)
            .map_err(|source| RigidStepError::Detect { step, t, source })?;
        phases.enter(StepPhase::Assembly);
        self.index_set(scene, state, scratch);
        let active = &scratch.active;
        let m = active.len();
        let n = state.len();

        let adjacency = contact_adjacency(active, n);

        let start: Vec<BodyState> = state.to_vec();
        // The joints' velocity rows at the poses of t_k (constant over the Newton iterates).
        let mut joint_rows = Vec::new();
        for joint in &scene.joints {
            joint.jacobian(&start, &mut joint_rows);
        }
        let mut lambda = DVector::zeros(joint_rows.len());
        let mut v_next: Vec<V3> = start.iter().map(|s| v3(s.velocity)).collect();
        let mut w_next: Vec<V3> = start.iter().map(|s| v3(s.angular_velocity)).collect();
        let mut j_inv = vec![Matrix3::<f64>::identity(); n];
        let mut v_free = vec![V3::zeros(); n];
        let mut w_free = vec![V3::zeros(); n];
        let warm = self.params.warm_start;
        let mut impulse = scratch.warm_start(warm);
        let mut report = StepReport {
            contacts: m,
            ..StepReport::default()
        };
        let mut residual = f64::INFINITY;
        for iterate in 1..=self.params.newton_max_iterations {
            phases.enter(StepPhase::Update);
            report.newton_iterations = iterate;
            self.free_twists(
                scene,
                &start,
                &w_next,
                (&mut j_inv, &mut v_free, &mut w_free),
                (step, t),
            )?;
            let inverse_mass = inverse_masses(scene, &j_inv);
            let condensed = (!joint_rows.is_empty())
                .then(|| Condensed::new(joint_rows.clone(), &inverse_mass, &v_free, &w_free));
            if m > 0 {
                phases.enter(StepPhase::Assembly);
                let problem = self.friction_problem(
                    scene,
                    active,
                    &adjacency,
                    &j_inv,
                    (&v_free, &w_free),
                    condensed.as_ref(),
                );
                phases.enter(StepPhase::Solve);
                if !warm {
                    impulse.fill(0.0);
                }
                let solved = self.solve_friction(problem, &impulse, phases, (step, t))?;
                phases.enter(StepPhase::Update);
                report.friction_iterations += solved.iterations;
                report.friction_error = solved.error;
                report.friction_accepted |= solved.accepted;
                impulse = solved.impulse;
            }
            // (v, Ω)^{i+1} = free + M⁻¹ (Gᵀ P + Jᵀ Λ), Λ = −A⁺ J (free + M⁻¹ Gᵀ P), and the
            // residual of (1b) there.
            let total = total_impulses(
                (&adjacency, active, &impulse),
                condensed.as_ref(),
                &inverse_mass,
                (&v_free, &w_free),
                &mut lambda,
            );
            residual = self.next_twists(
                scene,
                &start,
                &total,
                (&v_free, &w_free, &j_inv),
                (&mut v_next, &mut w_next),
            );
            if residual <= self.params.newton_tolerance {
                break;
            }
        }
        if residual > self.params.newton_tolerance {
            return Err(RigidStepError::Newton {
                step,
                t,
                iterations: report.newton_iterations,
                residual,
            });
        }

        self.finish(
            scene,
            &start,
            (&v_next, &w_next),
            active,
            &impulse,
            state,
            &mut report,
            step,
            t,
        )?;
        scratch.impulse = impulse;
        scratch.keep_impulses();
        if !joint_rows.is_empty() {
            self.finish_joints(scene, &start, &joint_rows, &lambda, state, &mut report);
        }
        scratch.found_valid = false;
        phases.enter(StepPhase::Detection);
        scratch
            .detect(scene, state, detector)
            .map_err(|source| RigidStepError::Detect {
                step,
                t: t + h,
                source,
            })?;
        Ok(report)
    }

    /// The one-step friction problem (`problem`, or why it could not be built) solved from
    /// `impulse`: its solution, or, when the solver spends its budget above the tolerance and
    /// its best iterate's error is within `accept_error`, that iterate, accepted (module
    /// documentation, *Unsolved friction problems*).
    fn solve_friction(
        &self,
        problem: Result<Fc3dProblem, Fc3dError>,
        impulse: &[f64],
        phases: &mut dyn StepPhases,
        (step, t): (u64, f64),
    ) -> Result<FrictionSolve, RigidStepError> {
        // Sweeps stalled within the acceptance bound stop there (`stall_sweeps`).
        let options = Fc3dOptions {
            stall: self
                .params
                .accept_error
                .zip(self.params.stall_sweeps)
                .map(|(below, sweeps)| Fc3dStall { sweeps, below }),
            ..self.params.fc3d
        };
        let outcome = problem.and_then(|problem| {
            phases.problem(&problem, impulse);
            solve_fc3d_from(&problem, &options, impulse)
        });
        match outcome {
            Ok(s) => Ok(FrictionSolve {
                impulse: s.r,
                iterations: s.iterations,
                error: s.error,
                accepted: false,
            }),
            Err(Fc3dError::NotConverged {
                iterations,
                error,
                best,
                ..
            }) if self.params.accept_error.is_some_and(|bound| error <= bound) => {
                Ok(FrictionSolve {
                    impulse: best,
                    iterations,
                    error,
                    accepted: true,
                })
            }
            Err(source) => Err(RigidStepError::Friction {
                step,
                t,
                contacts: impulse.len() / 3,
                source,
            }),
        }
    }

    /// The free twist of each free body at the Newton iterate (v, Ω)^i: v_free = v_k + h g, and
    /// Ω_free = Ω^i − J⁻¹ r(Ω^i), with r the residual of (1b) without impulses, r(Ω) =
    /// I (Ω − Ω_k) + h Ω_{k+θ} × I Ω_{k+θ}, and J = I + hθ (Ω_{k+θ}^× I − (I Ω_{k+θ})^×) its
    /// Jacobian, whose inverse `j_inv` also maps the impulses' moments to Ω.
    #[allow(clippy::type_complexity)]
    fn free_twists(
        &self,
        scene: &RigidScene,
        start: &[BodyState],
        w_next: &[V3],
        (j_inv, v_free, w_free): (&mut [Matrix3<f64>], &mut [V3], &mut [V3]),
        (step, t): (u64, f64),
    ) -> Result<(), RigidStepError> {
        let (h, theta) = (self.h, self.params.theta);
        let gravity = v3(scene.gravity);
        for (b, body) in scene.bodies.iter().enumerate() {
            if body.fixed {
                continue;
            }
            let inertia = Matrix3::from_diagonal(&v3(body.inertia));
            let w_k = v3(start[b].angular_velocity);
            let w_theta = (1.0 - theta) * w_k + theta * w_next[b];
            let iw = inertia * w_theta;
            let jac = inertia + h * theta * (skew(&w_theta) * inertia - skew(&iw));
            j_inv[b] =
                jac.try_inverse()
                    .ok_or(RigidStepError::SingularIteration { step, t, body: b })?;
            let r_free = inertia * (w_next[b] - w_k) + h * w_theta.cross(&iw);
            w_free[b] = w_next[b] - j_inv[b] * r_free;
            v_free[b] = v3(start[b].velocity) + h * gravity;
        }
        Ok(())
    }

    /// The next Newton iterate (v, Ω)^{i+1} = free + M⁻¹ (the bodies' total impulses `total`),
    /// and the largest scaled residual of (1b) there over the free bodies.
    fn next_twists(
        &self,
        scene: &RigidScene,
        start: &[BodyState],
        total: &[(V3, V3)],
        (v_free, w_free, j_inv): (&[V3], &[V3], &[Matrix3<f64>]),
        (v_next, w_next): (&mut [V3], &mut [V3]),
    ) -> f64 {
        let (h, theta) = (self.h, self.params.theta);
        let mut worst: f64 = 0.0;
        for (b, body) in scene.bodies.iter().enumerate() {
            if body.fixed {
                continue;
            }
            let (lin, ang) = total[b];
            v_next[b] = v_free[b] + lin / body.mass;
            w_next[b] = w_free[b] + j_inv[b] * ang;
            let inertia = Matrix3::from_diagonal(&v3(body.inertia));
            let w_k = v3(start[b].angular_velocity);
            let w_theta = (1.0 - theta) * w_k + theta * w_next[b];
            let change = inertia * (w_next[b] - w_k);
            let gyro = h * w_theta.cross(&(inertia * w_theta));
            let r = change + gyro - ang;
            // The size of the terms of (1b): the angular momenta, the gyroscopic term and
            // the impulse (the momenta keep the scale when the others are at round-off).
            let momentum = (inertia * w_k).amax() + (inertia * w_next[b]).amax();
            let scale = momentum + gyro.amax() + ang.amax();
            if r.amax() > 0.0 {
                worst = worst.max(r.amax() / scale);
            }
        }
        worst
    }

    /// The end of a step: (1c) for each free body (positions by the velocities at k + θ, the
    /// orientation by the exponential map of h Ω_{k+θ}), then the works of the impulses on
    /// U_{k+θ} (normal: `work_contact`, tangential: `work_friction`).
    #[allow(clippy::too_many_arguments)]
    fn finish(
        &self,
        scene: &RigidScene,
        start: &[BodyState],
        (v_next, w_next): (&[V3], &[V3]),
        active: &[ActiveContact],
        impulse: &[f64],
        state: &mut [BodyState],
        report: &mut StepReport,
        step: u64,
        t: f64,
    ) -> Result<(), RigidStepError> {
        let (h, theta) = (self.h, self.params.theta);
        let n = state.len();
        // (1c) and the works of the impulses on U_{k+θ}.
        let mut theta_twist = vec![(V3::zeros(), V3::zeros()); n];
        for (b, body) in scene.bodies.iter().enumerate() {
            if body.fixed {
                continue;
            }
            let v_theta = (1.0 - theta) * v3(start[b].velocity) + theta * v_next[b];
            let w_theta = (1.0 - theta) * v3(start[b].angular_velocity) + theta * w_next[b];
            theta_twist[b] = (v_theta, w_theta);
            let x = v3(start[b].position) + h * v_theta;
            let q = start[b].rotation() * UnitQuaternion::from_scaled_axis(h * w_theta);
            let q = UnitQuaternion::new_normalize(q.into_inner());
            let s = &mut state[b];
            s.position = [x.x, x.y, x.z];
            let qi: &Quaternion<f64> = q.as_ref();
            s.orientation = [qi.w, qi.i, qi.j, qi.k];
            s.velocity = [v_next[b].x, v_next[b].y, v_next[b].z];
            s.angular_velocity = [w_next[b].x, w_next[b].y, w_next[b].z];
            let finite = s.position.iter().chain(&s.orientation).chain(&s.velocity);
            if !finite.chain(&s.angular_velocity).all(|x| x.is_finite()) {
                return Err(RigidStepError::NotFinite {
                    step,
                    t: t + h,
                    body: b,
                });
            }
        }
        if active.is_empty() {
            return Ok(());
        }
        // The twists at k and k + 1 (zero for fixed bodies, as in theta_twist), for the split
        // of the tangential work by friction::split_tangential_work.
        let twist_at = |end: bool| -> Vec<(V3, V3)> {
            scene
                .bodies
                .iter()
                .enumerate()
                .map(|(b, body)| match (body.fixed, end) {
                    (true, _) => (V3::zeros(), V3::zeros()),
                    (false, false) => (v3(start[b].velocity), v3(start[b].angular_velocity)),
                    (false, true) => (v_next[b], w_next[b]),
                })
                .collect()
        };
        let (start_twist, end_twist) = (twist_at(false), twist_at(true));
        for (c, contact) in active.iter().enumerate() {
            let u = local_velocity(contact, &theta_twist);
            let p = &impulse[3 * c..3 * c + 3];
            report.work_contact += p[0] * u[0];
            let work = p[1] * u[1] + p[2] * u[2];
            let (u0, u1) = (
                local_velocity(contact, &start_twist),
                local_velocity(contact, &end_twist),
            );
            let at_start = p[1] * u0[1] + p[2] * u0[2];
            let at_end = p[1] * u1[1] + p[2] * u1[2];
            let split = split_tangential_work(work, theta, at_start, at_end);
            report.work_friction += split.friction;
            report.work_contact += split.contact;
        }
        Ok(())
    }

    /// The joints' end of a step: the work of their impulses on (v, Ω)_{k+θ}, then the
    /// projection of the poses onto φ = 0 ([`super::joint`]) and its residual.
    fn finish_joints(
        &self,
        scene: &RigidScene,
        start: &[BodyState],
        rows: &[JointRow],
        lambda: &DVector<f64>,
        state: &mut [BodyState],
        report: &mut StepReport,
    ) {
        let theta = self.params.theta;
        let twist: Vec<(V3, V3)> = start
            .iter()
            .zip(state.iter())
            .map(|(a, b)| {
                let mix = |x: [f64; 3], y: [f64; 3]| (1.0 - theta) * v3(x) + theta * v3(y);
                (
                    mix(a.velocity, b.velocity),
                    mix(a.angular_velocity, b.angular_velocity),
                )
            })
            .collect();
        report.work_joint = rows
            .iter()
            .enumerate()
            .map(|(j, r)| lambda[j] * r.velocity(&twist))
            .sum();
        let inverse_mass: Vec<InverseMass> = scene
            .bodies
            .iter()
            .map(|b| InverseMass {
                linear: if b.fixed { 0.0 } else { 1.0 / b.mass },
                angular: if b.fixed {
                    Matrix3::zeros()
                } else {
                    Matrix3::from_diagonal(&v3(b.inertia.map(|i| 1.0 / i)))
                },
            })
            .collect();
        report.position_residual = project(
            &scene.joints,
            &inverse_mass,
            state,
            self.params.projection_tolerance,
            self.params.projection_max_iterations,
        )
        .residual;
    }

    /// The index set of the contact points found at t_k: predicted gap g + γ h U_{n,k} ≤ margin
    /// (or ≤ `activation_gap`).
    fn index_set(&self, scene: &RigidScene, state: &[BodyState], scratch: &mut RigidScratch) {
        let threshold = self.params.activation_gap.unwrap_or(scene.margin);
        scratch.active.clear();
        scratch.active_points.clear();
        let twist: Vec<(V3, V3)> = state
            .iter()
            .map(|s| (v3(s.velocity), v3(s.angular_velocity)))
            .collect();
        for point in &scratch.found {
            let sides = [0, 1].map(|s| {
                let b = point.bodies[s];
                (!scene.bodies[b].fixed).then(|| (b, jacobian_block(point, s, &state[b])))
            });
            let law = scene.law(point.bodies[0], point.bodies[1]);
            let mut contact = ActiveContact {
                sides,
                u_start: [0.0; 3],
                restitution: law.restitution,
                friction: law.friction,
            };
            contact.u_start = local_velocity(&contact, &twist);
            if point.gap + self.params.gamma * self.h * contact.u_start[0] <= threshold {
                scratch.active.push(contact);
                scratch.active_points.push(*point);
            }
        }
    }

    /// W = Σ_s G_{c,s} M_s⁻¹ G_{d,s}ᵀ over the bodies contacts c and d share, and
    /// q = G (v, Ω)_free + (e U_{n,k}, 0, 0); with joints, condensed ([`Condensed`]):
    /// W − C A⁺ Cᵀ and q at the free velocity that satisfies the joints.
    fn friction_problem(
        &self,
        scene: &RigidScene,
        active: &[ActiveContact],
        adjacency: &[Vec<(usize, usize)>],
        j_inv: &[Matrix3<f64>],
        (v_free, w_free): (&[V3], &[V3]),
        condensed: Option<&Condensed>,
    ) -> Result<Fc3dProblem, Fc3dError> {
        let m = active.len();
        let mut blocks = Vec::new();
        // J⁻¹ times the angular part of each row of the blocks touching the body, once a body.
        let mut turned: Vec<[V3; 3]> = Vec::new();
        for (b, touching) in adjacency.iter().enumerate() {
            if touching.is_empty() {
                continue;
            }
            let inv_mass = 1.0 / scene.bodies[b].mass;
            turned.clear();
            turned.extend(touching.iter().map(|&(d, sd)| {
                active[d].sides[sd].map_or([V3::zeros(); 3], |(_, gd)| {
                    gd.map(|row| j_inv[b] * V3::new(row[3], row[4], row[5]))
                })
            }));
            for &(c, sc) in touching {
                let Some((_, gc)) = active[c].sides[sc] else {
                    continue;
                };
                for (&(d, sd), turned_d) in touching.iter().zip(&turned) {
                    let Some((_, gd)) = active[d].sides[sd] else {
                        continue;
                    };
                    let mut block = [0.0; 9];
                    for (i, row_c) in gc.iter().enumerate() {
                        let a_c = V3::new(row_c[0], row_c[1], row_c[2]);
                        let b_c = V3::new(row_c[3], row_c[4], row_c[5]);
                        for (j, row_d) in gd.iter().enumerate() {
                            let a_d = V3::new(row_d[0], row_d[1], row_d[2]);
                            block[3 * i + j] = inv_mass * a_c.dot(&a_d) + b_c.dot(&turned_d[j]);
                        }
                    }
                    blocks.push((c, d, block));
                }
            }
        }
        let mut free: Vec<(V3, V3)> = v_free.iter().copied().zip(w_free.iter().copied()).collect();
        if let Some(c) = condensed {
            free = c.free.clone();
            c.add_delassus_correction(active, &mut blocks);
        }
        let mut q = Vec::with_capacity(3 * m);
        let mut mu = Vec::with_capacity(m);
        for contact in active {
            let u = local_velocity(contact, &free);
            q.extend([u[0] + contact.restitution * contact.u_start[0], u[1], u[2]]);
            mu.push(contact.friction);
        }
        let w = BlockCsr::from_blocks(m, &blocks)?;
        Ok(Fc3dProblem { w, q, mu })
    }
}

/// The joints condensed out of a Newton iterate's one-step problem: with the joint rows J at
/// t_k, A = J M⁻¹ Jᵀ (M⁻¹ = diag(m⁻¹, J_Ω⁻¹) of the iterate) and its pseudo-inverse A⁺, the
/// equality J (v, Ω)^{i+1} = 0 is solved exactly for the joints' impulse Λ given the contacts':
///
/// ```text
/// Λ = −A⁺ J ((v, Ω)_free + M⁻¹ Gᵀ P)
/// ```
///
/// and substituting it leaves the contacts' FC3D problem on the condensed Delassus operator and
/// free velocity (a Schur complement; the equality blocks of Siconos' GenericMechanical problem
/// solved by their own diagonal block, here once and for all):
///
/// ```text
/// W' = W − C A⁺ Cᵀ,   C = G M⁻¹ Jᵀ,   q' = G (free + M⁻¹ Jᵀ Λ₀) + (e U_{n,k}, 0, 0),   Λ₀ = −A⁺ J free
/// ```
struct Condensed {
    rows: Vec<JointRow>,
    /// A⁺.
    a_plus: DMatrix<f64>,
    /// M⁻¹ J_jᵀ per row j: the (body, v, Ω) it moves.
    moved: Vec<Vec<(usize, V3, V3)>>,
    /// free + M⁻¹ Jᵀ Λ₀ per body.
    free: Vec<(V3, V3)>,
}

impl Condensed {
    fn new(
        rows: Vec<JointRow>,
        inverse_mass: &[InverseMass],
        v_free: &[V3],
        w_free: &[V3],
    ) -> Self {
        let a_plus = joint_operator(&rows, inverse_mass);
        let moved: Vec<Vec<(usize, V3, V3)>> = rows
            .iter()
            .map(|r| {
                r.sides
                    .iter()
                    .flatten()
                    .map(|(b, row)| {
                        let (v, w) = inverse_mass[*b].twist(row);
                        (*b, v, w)
                    })
                    .collect()
            })
            .collect();
        let mut free: Vec<(V3, V3)> = v_free.iter().copied().zip(w_free.iter().copied()).collect();
        let lambda0 =
            -(&a_plus * DVector::from_iterator(rows.len(), rows.iter().map(|r| r.velocity(&free))));
        for (j, m) in moved.iter().enumerate() {
            for (b, v, w) in m {
                free[*b].0 += lambda0[j] * v;
                free[*b].1 += lambda0[j] * w;
            }
        }
        Self {
            rows,
            a_plus,
            moved,
            free,
        }
    }

    /// Λ = −A⁺ J (v, Ω) for the twist free + M⁻¹ Gᵀ P.
    fn multipliers(&self, twist: &[(V3, V3)]) -> DVector<f64> {
        let jv =
            DVector::from_iterator(self.rows.len(), self.rows.iter().map(|r| r.velocity(twist)));
        -(&self.a_plus * jv)
    }

    /// Appends the blocks of −C A⁺ Cᵀ to W's blocks (only contacts on jointed bodies have a
    /// row of C).
    fn add_delassus_correction(
        &self,
        active: &[ActiveContact],
        blocks: &mut Vec<(usize, usize, [f64; 9])>,
    ) {
        let nj = self.rows.len();
        let mut coupled: Vec<(usize, DMatrix<f64>)> = Vec::new();
        for (c, contact) in active.iter().enumerate() {
            let mut block = DMatrix::zeros(3, nj);
            let mut any = false;
            for (b, g) in contact.sides.iter().flatten() {
                for (j, m) in self.moved.iter().enumerate() {
                    for (body, v, w) in m {
                        if body != b {
                            continue;
                        }
                        any = true;
                        for (i, row) in g.iter().enumerate() {
                            block[(i, j)] += row[0] * v.x
                                + row[1] * v.y
                                + row[2] * v.z
                                + row[3] * w.x
                                + row[4] * w.y
                                + row[5] * w.z;
                        }
                    }
                }
            }
            if any {
                coupled.push((c, block));
            }
        }
        for (c, cc) in &coupled {
            let left = cc * &self.a_plus;
            for (d, cd) in &coupled {
                let product = &left * cd.transpose();
                let mut block = [0.0; 9];
                for i in 0..3 {
                    for k in 0..3 {
                        block[3 * i + k] = -product[(i, k)];
                    }
                }
                blocks.push((*c, *d, block));
            }
        }
    }
}

/// The signed block σ_s G_{c,s} of side s (module documentation): rows n, t_1, t_2, each
/// (dᵀ, (Rᵀ(r × d))ᵀ), times −1 for side 0.
fn jacobian_block(point: &ContactPoint, side: usize, body: &BodyState) -> [[f64; 6]; 3] {
    let sign = if side == 0 { -1.0 } else { 1.0 };
    let r = v3(point.points[side]) - v3(body.position);
    let inverse = body.rotation().inverse();
    let frame = [point.normal, point.tangents[0], point.tangents[1]];
    frame.map(|d| {
        let d = v3(d);
        let a = inverse * r.cross(&d);
        [
            sign * d.x,
            sign * d.y,
            sign * d.z,
            sign * a.x,
            sign * a.y,
            sign * a.z,
        ]
    })
}

/// U = Σ_s σ_s G_{c,s} (v_s, Ω_s) for twists indexed by body.
fn local_velocity(contact: &ActiveContact, twist: &[(V3, V3)]) -> [f64; 3] {
    let mut u = [0.0; 3];
    for (b, g) in contact.sides.iter().flatten() {
        let (v, w) = &twist[*b];
        for (i, row) in g.iter().enumerate() {
            u[i] += row[0] * v.x
                + row[1] * v.y
                + row[2] * v.z
                + row[3] * w.x
                + row[4] * w.y
                + row[5] * w.z;
        }
    }
    u
}

/// Σ_c (σG_{c,s})ᵀ P_c on one body: its linear (world) and angular (body frame) parts.
fn generalized_impulse(
    touching: &[(usize, usize)],
    active: &[ActiveContact],
    impulse: &[f64],
) -> (V3, V3) {
    let mut lin = V3::zeros();
    let mut ang = V3::zeros();
    for &(c, s) in touching {
        if let Some((_, g)) = &active[c].sides[s] {
            for (i, row) in g.iter().enumerate() {
                let p = impulse[3 * c + i];
                lin += p * V3::new(row[0], row[1], row[2]);
                ang += p * V3::new(row[3], row[4], row[5]);
            }
        }
    }
    (lin, ang)
}

/// M⁻¹ = diag(m⁻¹ 1, J⁻¹) per body of a Newton iterate (zero for a fixed body's linear part).
fn inverse_masses(scene: &RigidScene, j_inv: &[Matrix3<f64>]) -> Vec<InverseMass> {
    scene
        .bodies
        .iter()
        .zip(j_inv)
        .map(|(body, j)| InverseMass {
            linear: if body.fixed { 0.0 } else { 1.0 / body.mass },
            angular: *j,
        })
        .collect()
}

/// Σ_c G_cᵀ P_c per body and, with joints, plus Jᵀ Λ with Λ = −A⁺ J (free + M⁻¹ Gᵀ P)
/// ([`Condensed::multipliers`], written into `lambda`).
#[allow(clippy::type_complexity)]
fn total_impulses(
    (adjacency, active, impulse): (&[Vec<(usize, usize)>], &[ActiveContact], &[f64]),
    condensed: Option<&Condensed>,
    inverse_mass: &[InverseMass],
    (v_free, w_free): (&[V3], &[V3]),
    lambda: &mut DVector<f64>,
) -> Vec<(V3, V3)> {
    let mut total: Vec<(V3, V3)> = adjacency
        .iter()
        .map(|touching| generalized_impulse(touching, active, impulse))
        .collect();
    if let Some(c) = condensed {
        let twist: Vec<(V3, V3)> = (0..total.len())
            .map(|b| {
                let m = &inverse_mass[b];
                let (dv, dw) = (m.linear * total[b].0, m.angular * total[b].1);
                (v_free[b] + dv, w_free[b] + dw)
            })
            .collect();
        *lambda = c.multipliers(&twist);
        add_joint_impulse(&c.rows, lambda, &mut total);
    }
    total
}

/// Which active contacts touch each of the `n` bodies, as (contact, side) pairs.
fn contact_adjacency(active: &[ActiveContact], n: usize) -> Vec<Vec<(usize, usize)>> {
    let mut adjacency: Vec<Vec<(usize, usize)>> = vec![Vec::new(); n];
    for (c, contact) in active.iter().enumerate() {
        for (s, side) in contact.sides.iter().enumerate() {
            if let Some((b, _)) = side {
                adjacency[*b].push((c, s));
            }
        }
    }
    adjacency
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(bodies: [usize; 2], features: [u32; 2], normal: [f64; 3]) -> ContactPoint {
        ContactPoint {
            bodies,
            points: [[0.0; 3]; 2],
            normal,
            tangents: super::super::tangent_basis(normal),
            gap: 0.0,
            features,
        }
    }

    /// The warm start reads the last impulse of the same contact (bodies and features) in the
    /// new contact frame, −P for the pair found in the other order, 0 for a new contact or with
    /// the warm start off.
    #[test]
    fn warm_start_matches_contacts_by_bodies_and_features() {
        let p = [0.3, -0.2, 5.0];
        let mut scratch = RigidScratch::resumed(vec![ContactImpulse {
            bodies: [1, 2],
            features: [3, 4],
            impulse: p,
        }]);
        let tilted = [0.6, 0.0, 0.8];
        scratch.active_points = vec![
            point([1, 2], [3, 4], tilted),
            point([2, 1], [4, 3], [-0.6, 0.0, -0.8]),
            point([1, 2], [3, 5], tilted),
        ];
        let start = scratch.warm_start(true);
        let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let frame = |n: [f64; 3]| {
            let [t1, t2] = super::super::tangent_basis(n);
            [n, t1, t2]
        };
        for (k, d) in frame(tilted).into_iter().enumerate() {
            assert_eq!(start[k], dot(p, d));
        }
        for (k, d) in frame([-0.6, 0.0, -0.8]).into_iter().enumerate() {
            assert_eq!(start[3 + k], -dot(p, d));
        }
        // Same bodies, another feature: a new contact.
        assert_eq!(&start[6..9], &[0.0; 3]);
        // The normal component of the matched contact is P·n = 0.18 + 4 = 4.18.
        assert!((start[0] - 4.18).abs() < 1e-15 && (start[3] - 4.18).abs() < 1e-15);
        assert_eq!(scratch.warm_start(false), vec![0.0; 9]);

        // keep_impulses writes back P_n n + P_t1 t_1 + P_t2 t_2: the same vector, to round-off.
        scratch.impulse = start;
        scratch.keep_impulses();
        let kept = scratch.previous_impulses();
        assert_eq!(kept.len(), 3);
        for (k, pk) in p.iter().enumerate() {
            assert!((kept[0].impulse[k] - pk).abs() < 1e-15);
            assert!((kept[1].impulse[k] + pk).abs() < 1e-15);
        }
        assert_eq!(kept[1].bodies, [2, 1]);
        assert_eq!(kept[2].impulse, [0.0; 3]);
    }
}
