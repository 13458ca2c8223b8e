//! The Moreau–Jean θ-scheme, Acary 2016 (21)–(24), and its variant (29).
//!
//! One step from (t_k, q_k, v_k) with step h:
//!
//! ```text
//! M(v_{k+1} − v_k) + h K q_{k+θ} + h C v_{k+θ} − h F_{k+θ} = G P_{k+1}          (21a)
//! q_{k+1} = q_k + h v_{k+θ}             (21b)   — variant: q_{k+1} = q_k + h v_{k+1/2}  (29b)
//! U_{k+1} = Gᵀ v_{k+1} (+ ẇ)            (21c)
//! 0 ≤ U^α_{k+1} + e_α U^α_k ⊥ P^α_{k+1} ≥ 0 on the index set (24), P^α = 0 elsewhere  (21d)
//! ```
//!
//! Eliminating q_{k+1} gives `Ŵ (v_{k+1} − v_k) = h(F_{k+θ} − K(q_k + θ h v_k) − C v_k) + G P`
//! with the iteration matrix `Ŵ = M + θhC + θ²h²K` (variant: `M + θhC + ½θh²K`), factorised
//! once per run. The free velocity is the solution with P = 0; the Delassus operator is
//! `W = Gᵀ Ŵ⁻¹ G`. With many single-dof contacts (a string on a bridge) W is never formed: the
//! impulse solves `Ŵ x = G P`, `0 ≤ Gᵀ(v_free + x) + e U_k ⊥ P ≥ 0` on the banded Ŵ
//! ([`crate::banded_contact`]), the same problem, so the energy terms below are unchanged.
//!
//! Energy terms (Lemma 1, (31)–(33)): `work_ext = h v_{k+θ}ᵀ F_{k+θ}`,
//! `work_damping = −h v_{k+θ}ᵀ C v_{k+θ}`, `work_contact = v_{k+θ}ᵀ G P_{k+1}` (= U_{k+θ}ᵀP for a
//! fixed obstacle), `numerical_dissipation = (½ − θ)(‖Δv‖²_M + ‖Δq‖²_K)`. For the variant the
//! same derivation with (29b) gives v_{k+1/2} in place of the outer v_{k+θ} of the three works
//! (`work_damping = −h v_{k+1/2}ᵀ C v_{k+θ}`) and `numerical_dissipation = (½ − θ)‖Δq‖²_K`,
//! which is (91) of Corollary 1 with γ = 2β = θ.
//!
//! Coulomb friction (a model with [`LinearModel::friction`], planar: one tangent row T_α per
//! contact; Moreau 1988, Jean 1999): when a contact of the index set has μ > 0, the impulse
//! solves the friction problem of [`crate::friction`] on the rows (G_α, T_α) of the active
//! contacts, Delassus operator `[G T]ᵀŴ⁻¹[G T]` (precomputed, [`FrictionDelassus`]), free local
//! velocity `(U_free + e U_k, T v_free)`, and (21a) gains `T P_t` on its right-hand side.
//! Multiplying it by the velocity of the works adds `work_friction = v_{k+θ}ᵀ T P_t`
//! (variant: v_{k+1/2}) = Σ P_t,α (θ U_t,{k+1} + (1 − θ) U_t,k) to Lemma 1's balance, which keeps
//! closing at round-off: `balance_residual` = ΔE − work_ext − work_damping − work_contact −
//! work_friction − numerical_dissipation. Coulomb's law on U_t,{k+1} makes the θ part ≤ 0; the
//! (1 − θ) part is ≤ 0 unless the sliding velocity reverses within the step, and on such a step
//! `work_friction` is the θ part and the rest goes to `work_contact`
//! ([`crate::friction::split_tangential_work`]), so work_friction ≤ 0 at every step and the
//! balance is unchanged. Without friction on the index set the step is the frictionless one,
//! operation for operation.

use super::{LinearScheme, LinearState, SchemeState, StepError, StepReport};
use crate::band::{BandCholesky, BandError, SymBand};
use crate::banded_contact::{BandedImpulse, restore_warm_start, uses_banded};
use crate::checkpoint::CheckpointError;
use crate::contact::{Delassus, FrictionDelassus, IndexSet, IndexSetRule};
use crate::energy::EnergyTerms;
use crate::friction::split_tangential_work;
use crate::lcp::LcpOptions;
use crate::lcp::active_set::ImpulseMap;
use crate::model::LinearModel;

/// Parameters of the Moreau–Jean scheme.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MoreauJeanParams {
    /// θ ∈ [0, 1]; ½ ≤ θ ≤ 1/(1+ē) makes the scheme dissipative (Proposition 1). Default ½.
    pub theta: f64,
    /// Position update (29b) `q_{k+1} = q_k + h v_{k+1/2}` instead of (21b).
    pub variant: bool,
    /// Index-set rule, (24) by default.
    pub index_set: IndexSetRule,
}

impl Default for MoreauJeanParams {
    fn default() -> Self {
        Self {
            theta: 0.5,
            variant: false,
            index_set: IndexSetRule::default(),
        }
    }
}

/// The Moreau–Jean scheme for one model and one step size.
#[derive(Debug, Clone)]
pub struct MoreauJean {
    params: MoreauJeanParams,
    h: f64,
    lcp: LcpOptions,
    /// Cholesky factor of Ŵ.
    factor: BandCholesky,
    delassus: Delassus,
    /// The banded impulse solver, when the model's contacts take it
    /// ([`crate::banded_contact::uses_banded`]); the dense `delassus` is then empty.
    banded: Option<BandedImpulse>,
    /// The Delassus operator with the tangent rows (models with friction).
    friction: Option<FrictionDelassus>,
    has_damping: bool,
    /// Energy (kinetic, strain) at the state of the last step, keyed by step number.
    last_energy: Option<(u64, f64, f64)>,
    /// F(t_{k+1}) of the last step and its time (NaN before the first step).
    f_next: Vec<f64>,
    f_next_t: f64,
    scratch: Scratch,
    index_set: IndexSet,
}

#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
struct Scratch {
    f_k: Vec<f64>,
    f_theta: Vec<f64>,
    tmp: Vec<f64>,
    work: Vec<f64>,
    v_theta: Vec<f64>,
    v_pos: Vec<f64>,
    dv: Vec<f64>,
    dq: Vec<f64>,
    /// Free tangential velocities T v_free of the active contacts (friction).
    rhs_t: Vec<f64>,
    /// Round-off levels of the friction problem's normal velocities.
    levels: Vec<f64>,
    /// P_t · U_t,k of each active contact, before v is updated (friction).
    tangential_start: Vec<f64>,
}

impl MoreauJean {
    /// Prepares the scheme: factorises Ŵ and precomputes the Delassus operator.
    pub fn new(
        model: &LinearModel,
        params: MoreauJeanParams,
        h: f64,
        lcp: LcpOptions,
    ) -> Result<Self, BandError> {
        let theta = params.theta;
        let k_coef = if params.variant {
            0.5 * theta * h * h
        } else {
            theta * theta * h * h
        };
        let w_hat = SymBand::combine(&[
            (1.0, &model.mass),
            (theta * h, &model.damping),
            (k_coef, &model.stiffness),
        ]);
        let factor = w_hat.cholesky()?;
        let banded = uses_banded(model, lcp.kind, false)
            .then(|| BandedImpulse::new(model, w_hat, ImpulseMap::Direct));
        let delassus = if banded.is_some() {
            Delassus::new(&factor, &[])
        } else {
            Delassus::new(&factor, &model.contacts)
        };
        let friction = model
            .has_friction()
            .then(|| FrictionDelassus::new(&factor, &model.contacts, &model.friction));
        let mut index_set = IndexSet::new(model.contacts.len());
        index_set.friction = friction.is_some();
        let n = model.dofs();
        let z = vec![0.0; n];
        Ok(Self {
            params,
            h,
            lcp,
            factor,
            delassus,
            banded,
            friction,
            has_damping: !model.damping.is_zero(),
            last_energy: None,
            f_next: z.clone(),
            f_next_t: f64::NAN,
            scratch: Scratch {
                f_k: z.clone(),
                f_theta: model.force.constant.clone(),
                tmp: z.clone(),
                work: z.clone(),
                v_theta: z.clone(),
                v_pos: z.clone(),
                dv: z.clone(),
                dq: z,
                rhs_t: Vec::new(),
                levels: Vec::new(),
                tangential_start: Vec::new(),
            },
            index_set,
        })
    }
}

impl LinearScheme for MoreauJean {
    fn step_size(&self) -> f64 {
        self.h
    }

    fn save_state(&self) -> SchemeState {
        SchemeState::MoreauJean(Box::new(self.checkpoint_state()))
    }

    fn restore_state(&mut self, state: SchemeState) -> Result<(), CheckpointError> {
        match state {
            SchemeState::MoreauJean(s) => self.restore_checkpoint_state(*s),
            other => Err(other.mismatch("moreau_jean")),
        }
    }

    fn algorithmic_energy(&self, model: &LinearModel, state: &LinearState) -> f64 {
        let (k, s) = model.energy(&state.q, &state.v);
        k + s
    }

    /// One step in the phases of Siconos' `MoreauJeanOSI`: the load at θ, the free velocity,
    /// the index set, the one-step problem (the impulse) and the update with Lemma 1's terms.
    fn step(
        &mut self,
        model: &LinearModel,
        state: &mut LinearState,
        report: &mut StepReport,
    ) -> Result<(), StepError> {
        let t_next = ((state.step + 1) as f64) * self.h;
        self.load_at_theta(model, state.t, t_next);
        self.free_velocity(model, state);
        self.update_index_set(model, state, t_next);
        self.one_step_problem(model, state, t_next, report)?;
        self.finish(model, state, t_next, report);
        Ok(())
    }
}

impl MoreauJean {
    /// F_{k+θ} = (1 − θ) F(t_k) + θ F(t_{k+1}) into `f_theta`; constant forces need no work per
    /// step.
    fn load_at_theta(&mut self, model: &LinearModel, t_k: f64, t_next: f64) {
        if model.force.harmonic.is_empty() {
            return;
        }
        let theta = self.params.theta;
        let s = &mut self.scratch;
        if self.f_next_t == t_k {
            s.f_k.copy_from_slice(&self.f_next);
        } else {
            model.force.eval_into(t_k, &mut s.f_k);
        }
        model.force.eval_into(t_next, &mut self.f_next);
        self.f_next_t = t_next;
        for ((ft, fk), fn_) in s.f_theta.iter_mut().zip(&s.f_k).zip(&self.f_next) {
            *ft = (1.0 - theta) * fk + theta * fn_;
        }
    }

    /// The free velocity increment into `dv`: Ŵ Δv_free = h (F_{k+θ} − K (q_k + θ h v_k) − C v_k),
    /// (21a) with P = 0.
    fn free_velocity(&mut self, model: &LinearModel, state: &LinearState) {
        let (h, theta) = (self.h, self.params.theta);
        let s = &mut self.scratch;
        for ((t, q), v) in s.tmp.iter_mut().zip(&state.q).zip(&state.v) {
            *t = q + theta * h * v;
        }
        model.stiffness.mul_into(&s.tmp, &mut s.work);
        for ((dv, f), kq) in s.dv.iter_mut().zip(&s.f_theta).zip(&s.work) {
            *dv = h * (f - kq);
        }
        if self.has_damping {
            model.damping.mul_into(&state.v, &mut s.work);
            for (dv, cv) in s.dv.iter_mut().zip(&s.work) {
                *dv -= h * cv;
            }
        }
        self.factor.solve_in_place(&mut s.dv);
    }

    /// The index set (24) (or the predicted-gap rule) with the free local velocity
    /// U_free = Gᵀ(v_k + Δv_free) + ẇ(t_{k+1}) of each contact.
    fn update_index_set(&mut self, model: &LinearModel, state: &LinearState, t_next: f64) {
        let (h, t_k) = (self.h, state.t);
        let dv = &self.scratch.dv;
        let units = self.banded.as_ref().and_then(BandedImpulse::units);
        if let Some(units) = units {
            self.index_set.assemble_unit(
                &self.params.index_set,
                units,
                state.step,
                &state.q,
                &state.v,
                dv,
                t_k,
                h,
            );
        } else {
            self.index_set.assemble(
                &self.params.index_set,
                &model.contacts,
                state.step,
                &state.q,
                &state.v,
                t_k,
                h,
                |c| c.project(&state.v) + c.project(dv) + c.w_rate(t_next),
            );
        }
    }

    /// The one-step problem (21c)–(21d) on the index set: the impulse LCP (or, with friction on
    /// the index set, the friction problem), whose impulse adds Ŵ⁻¹ G P (and Ŵ⁻¹ T P_t) to Δv.
    fn one_step_problem(
        &mut self,
        model: &LinearModel,
        state: &LinearState,
        t_next: f64,
        report: &mut StepReport,
    ) -> Result<(), StepError> {
        let step = state.step + 1;
        let s = &mut self.scratch;
        let friction = self.friction.as_mut().filter(|_| {
            self.index_set
                .active
                .iter()
                .any(|&a| model.friction[a].mu > 0.0)
        });
        if let Some(fd) = friction {
            s.rhs_t.clear();
            for &a in &self.index_set.active {
                let f = &model.friction[a];
                s.rhs_t.push(f.project(&state.v) + f.project(&s.dv));
            }
            report.lcp = fd
                .apply_impulse(
                    &self.index_set.active,
                    &self.index_set.rhs,
                    &s.rhs_t,
                    &model.friction,
                    &self.lcp,
                    &mut report.impulse,
                    &mut report.tangent_impulse,
                    &mut s.dv,
                    &mut s.levels,
                )
                .map_err(|source| StepError::Friction {
                    step,
                    t: t_next,
                    source,
                })?;
            self.index_set.record_levels(&s.levels, step);
        } else if let Some(banded) = self.banded.as_mut() {
            // The same problem on the banded Ŵ: Ŵ x = G P, Δv += x.
            report.tangent_impulse.fill(0.0);
            report.lcp = banded
                .apply(&mut self.index_set, &self.lcp, &mut report.impulse, step)
                .map_err(|source| StepError::Lcp {
                    step,
                    t: t_next,
                    source,
                })?;
            if report.lcp.size > 0 {
                for (dv, x) in s.dv.iter_mut().zip(banded.x()) {
                    *dv += x;
                }
            }
        } else {
            report.tangent_impulse.fill(0.0);
            report.lcp = self
                .delassus
                .apply_impulse(
                    &self.index_set.active,
                    &self.index_set.rhs,
                    &self.lcp,
                    &mut report.impulse,
                    &mut s.dv,
                )
                .map_err(|source| StepError::Lcp {
                    step,
                    t: t_next,
                    source,
                })?;
            self.index_set
                .record_roundoff(self.delassus.matrix(), &report.impulse, step);
        }

        Ok(())
    }

    /// The update (21b) or (29b) with the new state, and the terms of Lemma 1 (31)–(33) /
    /// Corollary 1 (91) with `work_friction`.
    fn finish(
        &mut self,
        model: &LinearModel,
        state: &mut LinearState,
        t_next: f64,
        report: &mut StepReport,
    ) {
        let (h, theta) = (self.h, self.params.theta);
        let step = state.step + 1;
        let n = state.q.len();
        let s = &mut self.scratch;
        // Energy of the state the step starts from (cached from the previous step).
        let (kin_k, strain_k) = match self.last_energy {
            Some((k, kin, st)) if k == state.step => (kin, st),
            _ => model.energy(&state.q, &state.v),
        };

        // v_{k+θ}: the damping work of the variant needs it besides v_{k+1/2} (in (21b) the two
        // are the same vector).
        let variant = self.params.variant;
        if self.has_damping && variant {
            for ((vt, v), dv) in s.v_theta.iter_mut().zip(&state.v).zip(&s.dv) {
                *vt = v + theta * dv;
            }
        }
        if self.friction.is_some() {
            s.tangential_start.clear();
            s.tangential_start.extend(
                self.index_set
                    .active
                    .iter()
                    .map(|&a| report.tangent_impulse[a] * model.friction[a].project(&state.v)),
            );
        }
        // Positions (21b) or (29b), the new state and the external work (31), in one sweep.
        let c_pos = if variant { 0.5 } else { theta };
        let work_ext = h * update_sweep(
            c_pos,
            h,
            &mut state.q[..n],
            &mut state.v[..n],
            &s.dv[..n],
            &s.f_theta[..n],
            &mut s.v_pos[..n],
        );

        // The other terms of Lemma 1 (33) / Corollary 1 (91).
        let work_damping = if self.has_damping {
            let v_theta = if variant { &s.v_theta } else { &s.v_pos };
            -h * model.damping.quad(&s.v_pos, v_theta)
        } else {
            0.0
        };
        let units = self.banded.as_ref().and_then(BandedImpulse::units);
        let mut work_contact: f64 = match units {
            Some(u) => u.work(&self.index_set.active, &report.impulse, &s.v_pos),
            None => self
                .index_set
                .active
                .iter()
                .map(|&a| report.impulse[a] * model.contacts[a].project(&s.v_pos))
                .sum(),
        };
        // The tangential impulses' work on v_{k+θ} (variant: v_{k+1/2}), split by
        // friction::split_tangential_work: what a reversing step moves goes to work_contact.
        let mut moved = 0.0;
        let work_friction: f64 = if self.friction.is_some() {
            self.index_set
                .active
                .iter()
                .zip(&s.tangential_start)
                .map(|(&a, &at_start)| {
                    let (pt, f) = (report.tangent_impulse[a], &model.friction[a]);
                    let work = pt * f.project(&s.v_pos);
                    let at_end = pt * f.project(&state.v);
                    let split = split_tangential_work(work, c_pos, at_start, at_end);
                    moved += split.contact;
                    split.friction
                })
                .sum()
        } else {
            0.0
        };
        if moved != 0.0 {
            work_contact += moved;
        }
        report.work_friction = work_friction;
        if theta != 0.5 {
            for (dq, vp) in s.dq.iter_mut().zip(&s.v_pos) {
                *dq = h * vp;
            }
        }
        let numerical_dissipation = match (theta == 0.5, variant) {
            (true, _) => 0.0,
            (false, true) => (0.5 - theta) * model.stiffness.quad(&s.dq, &s.dq),
            (false, false) => {
                (0.5 - theta) * (model.mass.quad(&s.dv, &s.dv) + model.stiffness.quad(&s.dq, &s.dq))
            }
        };
        state.t = t_next;
        state.step = step;

        let (kin, strain) = model.energy(&state.q, &state.v);
        self.last_energy = Some((step, kin, strain));
        let delta = (kin + strain) - (kin_k + strain_k);
        report.energy = EnergyTerms {
            kinetic: kin,
            strain,
            work_ext,
            work_damping,
            work_contact,
            numerical_dissipation,
            algorithmic_energy: kin + strain,
            balance_residual: delta
                - work_ext
                - work_damping
                - work_contact
                - work_friction
                - numerical_dissipation,
        };
        match units.filter(|_| model.friction.is_empty()) {
            Some(u) => u.fill(
                &state.q,
                &state.v,
                &mut report.gap,
                &mut report.local_velocity,
            ),
            None => report.fill_contacts(model, &state.q, &state.v, t_next),
        }
    }
}

/// What [`MoreauJean`] carries between steps: the energy and load cached at the end of the last
/// step, the scratch vectors (F at θ keeps its last value), the index set with its round-off
/// levels and, on the banded contact path, the solver's warm start (the active dofs of its last
/// solution).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct MoreauJeanState {
    last_energy: Option<(u64, f64, f64)>,
    f_next: Vec<f64>,
    f_next_t: f64,
    scratch: Scratch,
    index_set: IndexSet,
    banded_warm: Option<Vec<bool>>,
}

impl MoreauJean {
    fn checkpoint_state(&self) -> MoreauJeanState {
        MoreauJeanState {
            last_energy: self.last_energy,
            f_next: self.f_next.clone(),
            f_next_t: self.f_next_t,
            scratch: self.scratch.clone(),
            index_set: self.index_set.clone(),
            banded_warm: self.banded.as_ref().map(BandedImpulse::warm_start),
        }
    }

    fn restore_checkpoint_state(&mut self, s: MoreauJeanState) -> Result<(), CheckpointError> {
        if s.f_next.len() != self.f_next.len() || s.scratch.f_k.len() != self.scratch.f_k.len() {
            return Err(CheckpointError::Mismatch(format!(
                "moreau_jean state of {} dofs, the model has {}",
                s.f_next.len(),
                self.f_next.len()
            )));
        }
        restore_warm_start(self.banded.as_mut(), s.banded_warm)?;
        self.last_energy = s.last_energy;
        self.f_next = s.f_next;
        self.f_next_t = s.f_next_t;
        self.scratch = s.scratch;
        self.index_set = s.index_set;
        Ok(())
    }
}

/// The update sweep of a step: `v_pos = v + c Δv` (c = θ for (21b), ½ for (29b)), `q += h v_pos`,
/// `v += Δv`; returns `Σ_i v_pos,i F_i` (the external work (31) over h), summed in four
/// interleaved partial sums so that the sweep is not bound by the latency of one addition per
/// dof (the sum differs from the sequential one by round-off only).
fn update_sweep(
    c: f64,
    h: f64,
    q: &mut [f64],
    v: &mut [f64],
    dv: &[f64],
    f: &[f64],
    v_pos: &mut [f64],
) -> f64 {
    let one = |q: &mut f64, v: &mut f64, dv: f64, f: f64, vp: &mut f64| -> f64 {
        let p = *v + c * dv;
        *vp = p;
        *q += h * p;
        *v += dv;
        p * f
    };
    let split = q.len() - q.len() % 4;
    let (q4, qr) = q.split_at_mut(split);
    let (v4, vr) = v.split_at_mut(split);
    let (d4, dr) = dv.split_at(split);
    let (f4, fr) = f.split_at(split);
    let (p4, pr) = v_pos.split_at_mut(split);
    let mut acc = [0.0; 4];
    for ((((qc, vc), dc), fc), pc) in q4
        .chunks_exact_mut(4)
        .zip(v4.chunks_exact_mut(4))
        .zip(d4.chunks_exact(4))
        .zip(f4.chunks_exact(4))
        .zip(p4.chunks_exact_mut(4))
    {
        for l in 0..4 {
            acc[l] += one(&mut qc[l], &mut vc[l], dc[l], fc[l], &mut pc[l]);
        }
    }
    let mut tail = 0.0;
    for ((((q, v), dv), f), vp) in qr.iter_mut().zip(vr).zip(dr).zip(fr).zip(pr) {
        tail += one(q, v, *dv, *f, vp);
    }
    (acc[0] + acc[2]) + (acc[1] + acc[3]) + tail
}
