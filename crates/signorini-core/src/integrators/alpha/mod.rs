//! The nonsmooth Newmark / HHT / generalized-α / Krenk–Høgsberg (KH) family, Acary 2016
//! (25)–(30), with the algorithmic energy of Lemma 2 and Propositions 2–4.
//!
//! # The scheme
//!
//! One step from (t_k, q_k, v_k, a_k) with step h (Acary 2016, (25a)–(25i)):
//!
//! ```text
//! M v̇_{k+1} + K q_{k+1} + C v_{k+1} = F_{k+1}                                    (25a)
//! M w_{k+1} = G P_{k+1}                                                         (25b)
//! U_{k+1} = Gᵀ v_{k+1} (+ ẇ)                                                     (25c)
//! 0 ≤ U^α_{k+1} + e_α U^α_k ⊥ P^α_{k+1} ≥ 0 on the index set (24), P^α = 0 elsewhere  (25d)
//! (1 − α_m) a_{k+1} + α_m a_k = (1 − α_f) v̇_{k+1} + α_f v̇_k                       (25e)
//! q̃_{k+1} = q_k + h v_k + h²(½ − β) a_k + h² β a_{k+1}                            (25f)
//! ṽ_{k+1} = v_k + h(1 − γ) a_k + h γ a_{k+1}                                     (25g)
//! v_{k+1} = ṽ_{k+1} + w_{k+1}                                                    (25h)
//! q_{k+1} = q̃_{k+1} + (h/2) w_{k+1}                                              (25i)
//! ```
//!
//! Multiplying (25e) by M and using (25a) at t_k and t_{k+1} gives the characteristic relation
//! (53), `(1−α_m) M a_{k+1} + α_m M a_k = (1−α_f)[F − Kq − Cv]_{k+1} + α_f [F − Kq − Cv]_k`,
//! which is what a step solves (v̇_k never needs storing). The KH variant replaces (25a), (25e)
//! by (30), where damping and load take the inertial weights:
//! `(1−α_m)[M a + C v − F]_{k+1} + α_m[M a + C v − F]_k = −(1−α_f) K q_{k+1} − α_f K q_k`.
//! Both are `(1−α_M) M a_{k+1} + (1−α_C) C v_{k+1} + (1−α_K) K q_{k+1} − (1−α_L) F_{k+1} =
//! −α_M M a_k − α_C C v_k − α_K K q_k + α_L F_k` with per-term weights ([`Weighting`]).
//!
//! **No splitting.** Substituting (25f)–(25i) leaves two unknowns, a_{k+1} and P_{k+1}:
//! `S a_{k+1} = b_k − [(1−α_C) C + (1−α_K)(h/2) K] M⁻¹ G P_{k+1}` with the iteration matrix
//! `S = (1−α_M) M + (1−α_C) γ h C + (1−α_K) β h² K` (factorised once per run). Then
//! `v_{k+1} = v_free + Ŵ G P` with `Ŵ = M⁻¹ − γh S⁻¹[(1−α_C) C + (1−α_K)(h/2) K] M⁻¹`, and
//! the one LCP per step is `0 ≤ Gᵀ Ŵ G P + U_free + e∘U_k ⊥ P ≥ 0` on the index set: smooth
//! acceleration and impulse come out together. `Gᵀ Ŵ G = Gᵀ S⁻¹[(1−α_M) M + (1−α_K)h²(β − γ/2) K]
//! M⁻¹ G` is symmetric positive definite when C = 0 or C commutes with K M⁻¹ (Rayleigh damping)
//! and 2β ≥ γ; otherwise it is solved by Lemke's method as a general LCP.
//!
//! # Consistent start
//!
//! `a_0 = v̇_0 = M⁻¹(F_0 − K q_0 − C v_0)` (the equation of motion at t_0, contact forces taken
//! as zero) and filters `z_0 = x_0 = y_0 = 0`: then the residual `r_k = M a_k + C v_k + K q_k − F_k`
//! equals the filter force `f^A_k = (η/ν)[K z_k + C x_k − y_k]` of (51) at k = 0, and the
//! relation (53) carries the equality to every step, so the identities hold from step 1. A scheme
//! asked to step from a state it did not produce (a resumed run) starts consistently again there.
//!
//! # Energy (Lemma 2, Propositions 2–4)
//!
//! With `ν = ½ − α_m`, `η = α_f − α_m` (50) and the filters discretised by the mid-point rule
//! (48), `(½+ν) z_{k+1} + (½−ν) z_k = ν (q_{k+1} − q_k)`, and likewise x with v and y with F (52):
//!
//! * `algorithmic_energy` H (55) `= ½vᵀMv + ½qᵀKq + (h²/4)(2β − γ) aᵀMa + (η/(2ν²))(ν − γ + ½) zᵀKz`;
//! * `work_ext` `= Δqᵀ[F_{k,γ} − (η/ν) y_{k,γ}]` — (56) for Newmark and KH (no y filter), (79) for
//!   HHT, where `2y_{k+1} = F_{k+1} − F_k` turns it into `Δqᵀ[(1−α)F_{k,γ} + αF_{k−1,γ}]` (85);
//! * `work_damping` `= −Δqᵀ C[v_{k,γ} − (η/ν) x_{k,γ}]` — (57), (80) likewise;
//! * `work_contact` `= (Gᵀv_{k+1/2})ᵀ P_{k+1}`, that is `U_{k+1/2}ᵀ P_{k+1}` for a fixed obstacle
//!   (Lemma 3: ≤ 0); with a moving obstacle it is the work on the body;
//! * `numerical_dissipation` `= −½h²(γ − ½)(2β − γ)‖Δa‖²_M − (γ − ½ − η)‖Δq‖²_K
//!   − (η/ν)(ν − γ + ½)‖Δz‖²_K`, the right-hand side of (58) without the contact term: (73) for
//!   KH, (81) for HHT, (87) for Newmark (where the paper's `h/2` before ‖Δa‖² is `h²/2`, as (62)
//!   shows);
//! * `balance_residual` `= ΔH − work_ext − work_damping − work_contact − numerical_dissipation`,
//!   zero up to round-off: Lemma 2 (58) with the x, y filter terms moved into the two works.
//!
//! ΔH is evaluated in difference form (`½(v_{k+1}+v_k)ᵀ M Δv + …`) so that it keeps its relative
//! accuracy when H is large and the step changes it little.
//!
//! **Many contacts.** With single-dof contacts and a lumped mass the columns above are not
//! formed: the impulse solves `S x = R M⁻¹ G P` on the banded S (`BandedAlpha`,
//! [`crate::banded_contact`]), the same complementarity problem with the same W.
//!
//! **Coulomb friction** (a model with [`LinearModel::friction`], planar: one tangent row T_α per
//! contact, as for [`super::moreau_jean`]). The tangential impulse enters (25b) with the normal
//! one, `M w_{k+1} = G P_{k+1} + T P_t,{k+1}`, and the impulse law at velocity level becomes,
//! on the index set, Signorini–Newton in the normal rows and Coulomb's law on U_t,{k+1} =
//! T v_{k+1} in the tangent rows (the planar friction problem of [`crate::friction`], Moreau's
//! and Jean's law with the normal velocity U_{k+1} + e U_k). The tangent rows get their columns
//! as the normal rows do (`[G T]ᵀ Ŵ [G T]`, precomputed). Lemma 2's proof uses of (25b) only
//! that the impulse term is `v_{k+1/2}ᵀ M w_{k+1}` (it never uses the complementarity), so with
//! `M w = G P + T P_t` the balance (58) gains `work_friction = (Tᵀ v_{k+1/2})ᵀ P_t,{k+1}` =
//! Σ_α P_t,α ½(U_t,{k+1} + U_t,k) next to `work_contact`, and `balance_residual` =
//! ΔH − work_ext − work_damping − work_contact − work_friction − numerical_dissipation stays at
//! round-off. Coulomb's law makes P_t U_t,{k+1} = −μ P_n |U_t,{k+1}| ≤ 0; the ½ P_t U_t,k part is
//! ≤ 0 unless the sliding velocity reverses within the step, and on such a step `work_friction`
//! is ½ P_t U_t,{k+1} and the rest goes to `work_contact`
//! ([`crate::friction::split_tangential_work`], as for Moreau–Jean θ = ½): `work_friction` ≤ 0
//! at every step, the balance unchanged. Without friction on the index set the
//! step is the frictionless one, operation for operation. The banded path has no friction.
//!
//! When ν = 0 (α_m = ½) the filters (48) vanish; the scheme then requires η = 0 (Remark 1), and
//! the filter terms are zero.

use crate::band::{BandError, SymBand};
use crate::banded_contact::{BandedImpulse, restore_warm_start, uses_banded};
use crate::checkpoint::CheckpointError;
use crate::contact::{FrictionSubproblem, IndexSet, LcpStats};
use crate::friction::split_tangential_work;
use crate::integrators::{LinearScheme, LinearState, SchemeState, StepError, StepReport};
use crate::lcp::active_set::ImpulseMap;
use crate::lcp::{self, Lcp, LcpOptions};
use crate::model::LinearModel;

mod lanes;
mod params;
mod smooth;
mod sweeps;

pub use params::{AlphaParams, AlphaScheme, ParamError, Weighting};
pub use smooth::AlphaCoreState;
pub(crate) use smooth::{AlphaCore, ContactWork};

/// The nonsmooth α-family scheme (25) / (30) for one model and one step size.
#[derive(Debug, Clone)]
pub struct NonsmoothAlpha {
    params: AlphaParams,
    lcp: LcpOptions,
    core: AlphaCore,
    /// Per contact α (n entries each): the change of a_{k+1}, v_{k+1}, q_{k+1} per unit P^α.
    a_cols: Vec<f64>,
    v_cols: Vec<f64>,
    q_cols: Vec<f64>,
    /// Delassus operator `W = Gᵀ Ŵ G`, row-major m×m (not symmetric in general).
    w: Vec<f64>,
    index_set: IndexSet,
    lcp_m: Vec<f64>,
    /// The banded path (many single-dof contacts, lumped mass), instead of the dense columns.
    banded: Option<BandedAlpha>,
    /// The tangent rows of a model with Coulomb friction.
    friction: Option<AlphaFriction>,
}

/// The α-family's impulse with Coulomb friction (a model with [`LinearModel::friction`]): the
/// columns of the tangent rows T_α, formed as those of the normal rows (a tangential impulse
/// enters (25b) as `M w = G P + T P_t`), and the Delassus operator on the rows (G_α, T_α) of
/// every contact.
#[derive(Debug, Clone)]
struct AlphaFriction {
    /// Per contact α (n entries each): the change of a_{k+1}, v_{k+1}, q_{k+1} per unit P_t^α.
    a_cols: Vec<f64>,
    v_cols: Vec<f64>,
    q_cols: Vec<f64>,
    /// `[G T]ᵀ Ŵ [G T]`, row-major 2m×2m, rows and columns in the order (n_1, t_1, n_2, t_2, …).
    w: Vec<f64>,
    /// The problem on the index set, the free tangential velocities T v_free of its contacts
    /// and its round-off levels.
    sub: FrictionSubproblem,
    tangent_free: Vec<f64>,
    levels: Vec<f64>,
}

/// The α-family's impulse on the banded S: with `y = M⁻¹ G P` (the w_{k+1} of (25b)) and
/// `z = S⁻¹ B y`, `B = (1−α_C) C + (1−α_K)(h/2) K`, the impulse changes a_{k+1} by −z,
/// v_{k+1} by `y − γh z = S⁻¹ R y` and q_{k+1} by `(h/2) y − βh² z`, where
/// `R = S − γh B = (1−α_M) M + (1−α_K) h²(β − γ/2) K`: the problem is `S x = R M⁻¹ G P`
/// ([`ImpulseMap::Filtered`]), x the change of v_{k+1}.
#[derive(Debug, Clone)]
struct BandedAlpha {
    impulse: BandedImpulse,
    /// B.
    b: SymBand,
    /// Diagonal of M.
    mass: Vec<f64>,
    y: Vec<f64>,
    z: Vec<f64>,
}

/// How a unit impulse along one row r (a normal row G_α or a tangent row T_α) changes a step:
/// `x = M⁻¹ r` (the w_{k+1} of (25b)), `y = S⁻¹[(1−α_C) C + (1−α_K)(h/2) K] x`, and a_{k+1},
/// v_{k+1}, q_{k+1} change by −y, `x − γh y`, `(h/2) x − βh² y`.
struct ImpulseColumns<'a> {
    core: &'a AlphaCore,
    model: &'a LinearModel,
    h: f64,
    beta: f64,
    gamma: f64,
    /// 1 − α_K.
    stiffness: f64,
    /// 1 − α_C.
    damping: f64,
}

impl ImpulseColumns<'_> {
    /// The columns of the sparse row `row` into `[a, v, q]` (n entries each), with the
    /// buffers `[x, y, t]`.
    fn of_row(
        &self,
        row: &[(usize, f64)],
        [x, y, t]: &mut [Vec<f64>; 3],
        [a, v, q]: [&mut [f64]; 3],
    ) {
        let (h, beta, gamma, n) = (self.h, self.beta, self.gamma, x.len());
        x.fill(0.0);
        for &(i, g) in row {
            x[i] += g;
        }
        self.core.m_factor.solve_in_place(x);
        self.model.stiffness.mul_into(x, y);
        self.model.damping.mul_into(x, t);
        for i in 0..n {
            y[i] = self.stiffness * 0.5 * h * y[i] + self.damping * t[i];
        }
        self.core.s_factor.solve_in_place(y);
        for i in 0..n {
            a[i] = -y[i];
            v[i] = x[i] - gamma * h * y[i];
            q[i] = 0.5 * h * x[i] - beta * h * h * y[i];
        }
    }
}

impl AlphaFriction {
    /// The tangent columns of every contact and the Delassus operator on the rows (G_α, T_α),
    /// from the normal rows' velocity columns `v_cols`.
    fn new(
        model: &LinearModel,
        columns: &ImpulseColumns<'_>,
        v_cols: &[f64],
        buffers: &mut [Vec<f64>; 3],
    ) -> Self {
        let (n, m) = (model.dofs(), model.contacts.len());
        let mut a_cols = vec![0.0; n * m];
        let mut t_cols = vec![0.0; n * m];
        let mut q_cols = vec![0.0; n * m];
        for (a, f) in model.friction.iter().enumerate() {
            let at = a * n..(a + 1) * n;
            columns.of_row(
                &f.t,
                buffers,
                [
                    &mut a_cols[at.clone()],
                    &mut t_cols[at.clone()],
                    &mut q_cols[at],
                ],
            );
        }
        let mm = 2 * m;
        let mut w = vec![0.0; mm * mm];
        for (a, (c, f)) in model.contacts.iter().zip(&model.friction).enumerate() {
            for b in 0..m {
                for (r, col) in [&v_cols[b * n..(b + 1) * n], &t_cols[b * n..(b + 1) * n]]
                    .into_iter()
                    .enumerate()
                {
                    w[2 * a * mm + 2 * b + r] = c.project(col);
                    w[(2 * a + 1) * mm + 2 * b + r] = f.project(col);
                }
            }
        }
        Self {
            a_cols,
            v_cols: t_cols,
            q_cols,
            w,
            sub: FrictionSubproblem::new(m),
            tangent_free: Vec::new(),
            levels: Vec::new(),
        }
    }
}

impl NonsmoothAlpha {
    /// Prepares the scheme: factorises S and M, precomputes the impulse columns and the
    /// Delassus operator. `params` should have passed [`AlphaParams::validate`].
    pub fn new(
        model: &LinearModel,
        params: AlphaParams,
        h: f64,
        lcp: LcpOptions,
    ) -> Result<Self, BandError> {
        let core = AlphaCore::new(model, params.coefficients(), h)?;
        let w8 = params.weights();
        let (beta, gamma) = (params.beta, params.gamma);
        if uses_banded(model, lcp.kind, true) {
            let n = model.dofs();
            let s = SymBand::combine(&[
                (1.0 - w8.mass, &model.mass),
                ((1.0 - w8.damping) * gamma * h, &model.damping),
                ((1.0 - w8.stiffness) * beta * h * h, &model.stiffness),
            ]);
            let r = SymBand::combine(&[
                (1.0 - w8.mass, &model.mass),
                (
                    (1.0 - w8.stiffness) * h * h * (beta - 0.5 * gamma),
                    &model.stiffness,
                ),
            ]);
            let mass: Vec<f64> = (0..n).map(|i| model.mass.get(i, i)).collect();
            let d = mass.iter().map(|m| 1.0 / m).collect();
            let b = SymBand::combine(&[
                (1.0 - w8.damping, &model.damping),
                ((1.0 - w8.stiffness) * 0.5 * h, &model.stiffness),
            ]);
            return Ok(Self {
                params,
                lcp,
                core,
                a_cols: Vec::new(),
                v_cols: Vec::new(),
                q_cols: Vec::new(),
                w: Vec::new(),
                index_set: IndexSet::new(model.contacts.len()),
                lcp_m: Vec::new(),
                friction: None,
                banded: Some(BandedAlpha {
                    impulse: BandedImpulse::new(model, s, ImpulseMap::Filtered { r, d }),
                    b,
                    mass,
                    y: vec![0.0; n],
                    z: vec![0.0; n],
                }),
            });
        }
        let (n, m) = (model.dofs(), model.contacts.len());
        let mut a_cols = vec![0.0; n * m];
        let mut v_cols = vec![0.0; n * m];
        let mut q_cols = vec![0.0; n * m];
        let mut buffers = [vec![0.0; n], vec![0.0; n], vec![0.0; n]];
        let columns = ImpulseColumns {
            core: &core,
            model,
            h,
            beta,
            gamma,
            stiffness: 1.0 - w8.stiffness,
            damping: 1.0 - w8.damping,
        };
        for (a, c) in model.contacts.iter().enumerate() {
            let at = a * n..(a + 1) * n;
            columns.of_row(
                &c.g,
                &mut buffers,
                [
                    &mut a_cols[at.clone()],
                    &mut v_cols[at.clone()],
                    &mut q_cols[at],
                ],
            );
        }
        let mut w = vec![0.0; m * m];
        for (a, c) in model.contacts.iter().enumerate() {
            for b in 0..m {
                w[a * m + b] = c.project(&v_cols[b * n..(b + 1) * n]);
            }
        }
        let friction = model
            .has_friction()
            .then(|| AlphaFriction::new(model, &columns, &v_cols, &mut buffers));
        let mut index_set = IndexSet::new(model.contacts.len());
        index_set.friction = friction.is_some();
        Ok(Self {
            params,
            lcp,
            core,
            a_cols,
            v_cols,
            q_cols,
            w,
            index_set,
            lcp_m: Vec::new(),
            banded: None,
            friction,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &AlphaParams {
        &self.params
    }

    /// The smooth acceleration a_k of the last state this scheme produced (or of a consistent
    /// start at `state`).
    pub fn acceleration(&mut self, model: &LinearModel, state: &LinearState) -> &[f64] {
        self.core.ensure_history(model, state);
        &self.core.cur.a
    }
}

impl LinearScheme for NonsmoothAlpha {
    fn step_size(&self) -> f64 {
        self.core.h
    }

    fn save_state(&self) -> SchemeState {
        SchemeState::Alpha(Box::new(AlphaState {
            core: self.core.checkpoint_state(),
            index_set: self.index_set.clone(),
            lcp_m: self.lcp_m.clone(),
            banded_warm: self.banded.as_ref().map(|b| b.impulse.warm_start()),
        }))
    }

    fn restore_state(&mut self, state: SchemeState) -> Result<(), CheckpointError> {
        match state {
            SchemeState::Alpha(s) => {
                let AlphaState {
                    core,
                    index_set,
                    lcp_m,
                    banded_warm,
                } = *s;
                restore_warm_start(self.banded.as_mut().map(|b| &mut b.impulse), banded_warm)?;
                self.core.restore_checkpoint_state(core)?;
                self.index_set = index_set;
                self.lcp_m = lcp_m;
                Ok(())
            }
            other => Err(other.mismatch("the nonsmooth α-family")),
        }
    }

    fn algorithmic_energy(&self, model: &LinearModel, state: &LinearState) -> f64 {
        self.core.algorithmic_energy(model, state)
    }

    fn step(
        &mut self,
        model: &LinearModel,
        state: &mut LinearState,
        report: &mut StepReport,
    ) -> Result<(), StepError> {
        let h = self.core.h;
        let t_k = state.t;
        let step = state.step + 1;
        let t_next = self.core.predict(model, state);
        let n = state.q.len();
        let m = model.contacts.len();

        // Index set (24) and the LCP on the combined system (25c)–(25d).
        let v_free = &self.core.s.v;
        self.index_set.assemble(
            &self.params.index_set,
            &model.contacts,
            state.step,
            &state.q,
            &state.v,
            t_k,
            h,
            |c| c.local_velocity(v_free, t_next),
        );
        report.impulse.fill(0.0);
        report.lcp = LcpStats::default();
        if self.friction.is_some() {
            report.tangent_impulse.fill(0.0);
            report.work_friction = 0.0;
        }
        let friction_step = self.friction.is_some()
            && self
                .index_set
                .active
                .iter()
                .any(|&a| model.friction[a].mu > 0.0);
        if let Some(banded) = self.banded.as_mut() {
            report.lcp = banded
                .impulse
                .apply(&mut self.index_set, &self.lcp, &mut report.impulse, step)
                .map_err(|source| StepError::Lcp {
                    step,
                    t: t_next,
                    source,
                })?;
            if report.lcp.size > 0 {
                // y = M⁻¹ G P, z = S⁻¹ B y; a −= z, v += y − γh z, q += (h/2) y − βh² z.
                banded.y.fill(0.0);
                for &a in &self.index_set.active {
                    let (dof, coef) = banded.impulse.unit(a);
                    banded.y[dof] = coef * report.impulse[a] / banded.mass[dof];
                }
                banded.b.mul_into(&banded.y, &mut banded.z);
                self.core.s_factor.solve_in_place(&mut banded.z);
                let (beta, gamma) = (self.params.beta, self.params.gamma);
                let s = &mut self.core.s;
                for i in 0..n {
                    let (y, z) = (banded.y[i], banded.z[i]);
                    s.a[i] -= z;
                    s.v[i] += y - gamma * h * z;
                    s.q[i] += 0.5 * h * y - beta * h * h * z;
                }
            }
        } else if friction_step {
            self.friction_impulse(model, step, t_next, report)?;
        } else if !self.index_set.active.is_empty() {
            self.dense_impulse(n, m, step, t_next, report)?;
        }
        if self.banded.is_none() && !friction_step {
            self.index_set
                .record_roundoff(&self.w, &report.impulse, step);
        }
        let (work_contact, work_friction) = self.impulse_works(model, state, friction_step, report);
        self.core.finish(
            model,
            state,
            t_next,
            ContactWork::Impulse(work_contact),
            report,
        );
        if friction_step {
            report.work_friction = work_friction;
            report.energy.balance_residual -= work_friction;
        }
        Ok(())
    }
}

impl NonsmoothAlpha {
    /// The impulses' works of a step, against v_{k+1/2} (Lemma 2): `work_contact = (Gᵀ
    /// v_{k+1/2})ᵀ P_{k+1}` and, on a step with friction, `work_friction = (Tᵀ v_{k+1/2})ᵀ
    /// P_t,{k+1}` (module documentation); v_{k+1} is the scheme's, v_k the state's.
    fn impulse_works(
        &self,
        model: &LinearModel,
        state: &LinearState,
        friction_step: bool,
        report: &StepReport,
    ) -> (f64, f64) {
        // work_contact = (Gᵀ v_{k+1/2})ᵀ P_{k+1} (Lemma 2; U_{k+1/2}ᵀP for a fixed obstacle).
        let mut work_contact = 0.0;
        for &a in &self.index_set.active {
            let p = report.impulse[a];
            if p != 0.0 {
                let c = &model.contacts[a];
                work_contact += p * 0.5 * (c.project(&self.core.s.v) + c.project(&state.v));
            }
        }
        // work_friction = (Tᵀ v_{k+1/2})ᵀ P_t,{k+1}, the same term for the tangent rows, split
        // by friction::split_tangential_work (a reversing step moves part to work_contact).
        let mut work_friction = 0.0;
        if friction_step {
            for &a in &self.index_set.active {
                let pt = report.tangent_impulse[a];
                if pt != 0.0 {
                    let f = &model.friction[a];
                    let (end, start) = (f.project(&self.core.s.v), f.project(&state.v));
                    let work = pt * 0.5 * (end + start);
                    let split = split_tangential_work(work, 0.5, pt * start, pt * end);
                    work_friction += split.friction;
                    work_contact += split.contact;
                }
            }
        }
        (work_contact, work_friction)
    }

    /// The impulse LCP of the dense path (25c)–(25d) on the index set, `0 ≤ W_II P + U_free +
    /// e U_k ⊥ P ≥ 0`, and the impulse's change of a_{k+1}, v_{k+1}, q_{k+1} along the columns.
    fn dense_impulse(
        &mut self,
        n: usize,
        m: usize,
        step: u64,
        t_next: f64,
        report: &mut StepReport,
    ) -> Result<(), StepError> {
        self.lcp_m.clear();
        for &a in &self.index_set.active {
            for &b in &self.index_set.active {
                self.lcp_m.push(self.w[a * m + b]);
            }
        }
        let sol = lcp::solve(
            Lcp {
                m: &self.lcp_m,
                q: &self.index_set.rhs,
            },
            &self.lcp,
        )
        .map_err(|source| StepError::Lcp {
            step,
            t: t_next,
            source,
        })?;
        report.lcp = LcpStats {
            size: self.index_set.active.len(),
            iterations: sol.iterations,
            error: sol.error,
        };
        let s = &mut self.core.s;
        for (r, &a) in self.index_set.active.iter().enumerate() {
            let p = sol.z[r];
            report.impulse[a] = p;
            if p != 0.0 {
                let (ac, vc, qc) = (
                    &self.a_cols[a * n..(a + 1) * n],
                    &self.v_cols[a * n..(a + 1) * n],
                    &self.q_cols[a * n..(a + 1) * n],
                );
                for (((sa, sv), sq), ((ac, vc), qc)) in s.a[..n]
                    .iter_mut()
                    .zip(&mut s.v[..n])
                    .zip(&mut s.q[..n])
                    .zip(ac.iter().zip(vc).zip(qc))
                {
                    *sa += p * ac;
                    *sv += p * vc;
                    *sq += p * qc;
                }
            }
        }
        Ok(())
    }

    /// The impulse of a step with friction on its index set: the planar friction problem of
    /// [`crate::friction`] on the rows (G_α, T_α) of the active contacts, with free local
    /// velocities `(U_free + e U_k, T v_free)`; (P_n, P_t) change a_{k+1}, v_{k+1}, q_{k+1} along
    /// the normal and the tangent columns, and the round-off levels of the normal rows (both
    /// rows of a contact, which the solver couples) are kept for the next sign test.
    fn friction_impulse(
        &mut self,
        model: &LinearModel,
        step: u64,
        t_next: f64,
        report: &mut StepReport,
    ) -> Result<(), StepError> {
        let Some(fr) = self.friction.as_mut() else {
            return Ok(());
        };
        let n = model.dofs();
        let (active, rhs) = (&self.index_set.active, &self.index_set.rhs);
        let s = &mut self.core.s;
        fr.tangent_free.clear();
        fr.tangent_free
            .extend(active.iter().map(|&a| model.friction[a].project(&s.v)));
        let sol = fr
            .sub
            .solve(
                &fr.w,
                active,
                rhs,
                &fr.tangent_free,
                |a| model.friction[a].mu,
                &self.lcp,
            )
            .map_err(|source| StepError::Friction {
                step,
                t: t_next,
                source,
            })?;
        let k = active.len();
        fr.levels.clear();
        for (r, &a) in active.iter().enumerate() {
            let (pn, pt) = (sol.p[2 * r], sol.p[2 * r + 1]);
            report.impulse[a] = pn;
            report.tangent_impulse[a] = pt;
            let normal = (&self.a_cols, &self.v_cols, &self.q_cols);
            let tangent = (&fr.a_cols, &fr.v_cols, &fr.q_cols);
            for (p, (ac, vc, qc)) in [(pn, normal), (pt, tangent)] {
                if p != 0.0 {
                    let at = a * n..(a + 1) * n;
                    for (((sa, sv), sq), ((ac, vc), qc)) in s.a[..n]
                        .iter_mut()
                        .zip(&mut s.v[..n])
                        .zip(&mut s.q[..n])
                        .zip(ac[at.clone()].iter().zip(&vc[at.clone()]).zip(&qc[at]))
                    {
                        *sa += p * ac;
                        *sv += p * vc;
                        *sq += p * qc;
                    }
                }
            }
            fr.levels.push(fr.sub.level(r, &sol.p));
        }
        self.index_set.record_levels(&fr.levels, step);
        report.lcp = LcpStats {
            size: k,
            iterations: sol.iterations,
            error: sol.error,
        };
        Ok(())
    }
}

/// What [`NonsmoothAlpha`] carries between steps: its core's state and the index set with its
/// round-off levels.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct AlphaState {
    core: AlphaCoreState,
    index_set: IndexSet,
    lcp_m: Vec<f64>,
    /// The banded solver's warm start (the banded contact path only).
    banded_warm: Option<Vec<bool>>,
}
