//! A validated job and how to run it: [`Job::from_spec`] checks a [`JobSpec`] once and builds
//! its model and integrator; [`run`] runs it, reporting to an [`Observer`], and returns the
//! summary and any tables or figures the job makes.

mod analysis;
mod rigid;
mod soi2;
mod wave;

pub use rigid::rigid_params;

use crate::band::SymBand;
use crate::banded_contact::{banded_refusal, uses_banded};
use crate::checkpoint::{Checkpoint, CheckpointError};
use crate::contact::IndexSetRule;
use crate::contact_region::ContactRegion;
use crate::integrators::alpha::{AlphaParams, AlphaScheme, NonsmoothAlpha, ParamError};
use crate::integrators::moreau_jean::{MoreauJean, MoreauJeanParams};
use crate::integrators::position_contact::{PositionContact, PositionContactParams};
use crate::integrators::{LinearScheme, LinearState, OutputOptions, run_linear_from};
use crate::lagrangian::{StartProjection, UserModel};
use crate::lcp::{LcpOptions, LcpSolverKind};
use crate::model::{
    Contact, ContactFriction, Forcing, HarmonicLoad, LinearModel, ModelError,
    dense_contacts_too_large,
};
use crate::nonlinear::LagrangianSystem;
use crate::nonlinear::generalized_alpha::{
    JointedSystem, NonsmoothGeneralizedAlpha, NsAlphaParams, NsAlphaSummary, ns_alpha_columns,
};
use crate::nonlinear::moreau_jean::{
    NewtonOptions, NonlinearMoreauJean, NonlinearMoreauJeanParams, NonlinearState, has_friction,
    nonlinear_columns,
};
use crate::nonlinear::run::run_user_model;
use crate::observer::{Columns, Observer, Progress, StepRecord};
use crate::outcome::{
    LinearSummary, NonlinearSummary, RunError, RunOutput, RunSummary, SummaryBody, SummaryHeader,
};
use crate::rigid::DetectorFactory;
use crate::scenes::Bar;
use crate::soi2::method::NewtonStrategy;
use crate::soi2::run::Soi2Job;
use crate::spec::support::{self, Feature, ModelFamily};
use crate::spec::{
    IntegratorSpec, JobSpec, LagrangianSpec, LinearSpec, ModelSpec, MoreauJeanSpec, NsAlphaSpec,
    PositionContactSpec, Probes, SchemeFamily, SpecError, Steps, mismatch,
};
use crate::trace::EnergyTrace;
use crate::wfem::job::WaveJob;
use std::ops::ControlFlow;

/// Size of a job, for the service's limits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct JobSize {
    /// Degrees of freedom.
    pub dofs: u64,
    /// Time steps (or analysis tasks).
    pub steps: u64,
    /// Rough memory estimate of the recorded output, in bytes.
    pub output_bytes: u64,
}

/// A validated, ready-to-run job.
#[derive(Debug, Clone)]
pub struct Job {
    spec: JobSpec,
    kind: JobKind,
    /// How a `lagrangian` model's start was moved onto its joints (`model.project_onto_joints`).
    start: Option<StartProjection>,
}

#[derive(Debug, Clone)]
enum JobKind {
    Linear(Box<LinearJob>),
    Soi2(Box<Soi2Job>),
    Wave(Box<WaveJob>),
    Nonlinear(Box<NonlinearJob>),
    NsAlpha(Box<NsAlphaJob>),
    Rigid(Box<rigid::RigidJob>),
}

/// A `lagrangian` model (joints, contacts, both or neither) under the nonsmooth generalized-α
/// scheme of `nonlinear::generalized_alpha`.
#[derive(Debug, Clone)]
struct NsAlphaJob {
    model: UserModel,
    /// The scheme, built (and its parameters checked) at validation; each run clones it.
    scheme: NonsmoothGeneralizedAlpha,
    h: f64,
    steps: u64,
    output: OutputOptions,
}

/// A `lagrangian` model with contacts under the nonlinear Moreau–Jean time-stepping.
#[derive(Debug, Clone)]
struct NonlinearJob {
    model: UserModel,
    /// The scheme, built (and its parameters checked) at validation; each run clones it.
    scheme: NonlinearMoreauJean,
    h: f64,
    steps: u64,
    output: OutputOptions,
}

#[derive(Debug, Clone)]
struct LinearJob {
    model: LinearModel,
    scheme: LinearSchemeChoice,
    h: f64,
    steps: u64,
    lcp: LcpOptions,
    output: OutputOptions,
    /// The contacts of a distributed obstacle, for the `contact_region` chart.
    region: Option<RegionContacts>,
}

/// The contacts of a distributed obstacle: the first one's index, their abscissae, and the
/// touching threshold δ = 10⁻³ max|q₀| of the chart.
#[derive(Debug, Clone)]
struct RegionContacts {
    first: usize,
    x: Vec<f64>,
    delta: f64,
}

impl RegionContacts {
    /// For a `string` or a `bar` with an `obstacle`.
    fn of(spec: &ModelSpec, model: &LinearModel) -> Option<Self> {
        let (first, x) = match spec {
            ModelSpec::String(st) if st.obstacle.is_some() => {
                (0, (0..st.nodes).map(|j| st.x(j)).collect())
            }
            ModelSpec::Bar(b) if b.obstacle.is_some() => (
                1,
                b.resolve(Bar::default())
                    .obstacle_nodes()
                    .iter()
                    .map(|n| n.1)
                    .collect(),
            ),
            ModelSpec::DepBar(b) if b.obstacle.is_some() => (
                1,
                b.resolve(Bar::doyen_ern_piperno(100))
                    .obstacle_nodes()
                    .iter()
                    .map(|n| n.1)
                    .collect(),
            ),
            _ => return None,
        };
        let delta = 1e-3 * model.q0.iter().fold(0.0f64, |m, q| m.max(q.abs()));
        Some(Self { first, x, delta })
    }
}

#[derive(Debug, Clone)]
enum LinearSchemeChoice {
    MoreauJean(MoreauJeanParams),
    Alpha(AlphaParams),
    PositionContact(PositionContactParams),
}

impl LinearJob {
    /// The job of a linear scene `model` under a linear scheme.
    fn from_spec(model_spec: &ModelSpec, spec: &JobSpec) -> Result<LinearJob, SpecError> {
        let time = spec.time_section()?;
        let model = build_model(model_spec)?;
        let steps = time.steps(support::refusal(
            spec.integrator.scheme(),
            ModelFamily::Linear,
            Feature::VariableStep,
            "",
        ))?;
        let lcp = spec.contact_solver.options()?;
        let output = spec.output.options(Probes::Dofs(model.dofs()))?;
        let scheme = match &spec.integrator {
            IntegratorSpec::NsNewmark(_)
            | IntegratorSpec::NsHht(_)
            | IntegratorSpec::NsGeneralizedAlpha(_)
            | IntegratorSpec::NsKhAlpha(_) => {
                refuse_newton_strategy(
                    &spec.integrator,
                    "a linear model's step solves no nonlinear system",
                )?;
                LinearSchemeChoice::Alpha(alpha_params(&spec.integrator)?)
            }
            IntegratorSpec::NewmarkPositionContact(p) => {
                LinearSchemeChoice::PositionContact(position_contact_params(p, false)?)
            }
            IntegratorSpec::HhtPositionContact(p) => {
                LinearSchemeChoice::PositionContact(position_contact_params(p, true)?)
            }
            IntegratorSpec::MoreauJean(p) => {
                LinearSchemeChoice::MoreauJean(moreau_jean_params(p, false)?)
            }
            IntegratorSpec::MoreauJeanVariant(p) => {
                LinearSchemeChoice::MoreauJean(moreau_jean_params(p, true)?)
            }
            IntegratorSpec::Wfem(_)
            | IntegratorSpec::Soi2GeneralizedAlpha(_)
            | IntegratorSpec::Soi2Hht(_)
            | IntegratorSpec::HhtI3(_) => {
                return Err(mismatch(model_spec, spec.integrator.scheme()));
            }
        };
        check_contact_path(&model, &scheme, &lcp, spec.integrator.scheme())?;
        if model.has_friction() {
            support::check(
                spec.integrator.scheme(),
                ModelFamily::Linear,
                Feature::Friction,
                "model.friction > 0",
            )?;
        }
        Ok(LinearJob {
            region: RegionContacts::of(model_spec, &model),
            model,
            scheme,
            h: steps.h,
            steps: steps.count(),
            lcp,
            output,
        })
    }
}

/// The contact path of a linear job: `banded_active_set` only where the scheme and the model
/// take it ([`banded_refusal`]), and a dense path only where its operators Ŵ⁻¹G and W fit
/// ([`dense_contacts_too_large`]; the model checked it already unless its contacts could go
/// banded).
fn check_contact_path(
    model: &LinearModel,
    scheme: &LinearSchemeChoice,
    lcp: &LcpOptions,
    scheme_name: &str,
) -> Result<(), SpecError> {
    let lumped = matches!(scheme, LinearSchemeChoice::Alpha(_));
    let velocity_level = !matches!(scheme, LinearSchemeChoice::PositionContact(_));
    if lcp.kind == LcpSolverKind::BandedActiveSet {
        if !velocity_level {
            return Err(SpecError::new(
                "contact_solver.kind",
                format!(
                    "banded_active_set solves the impulse of moreau_jean and the nonsmooth α-family, not the position-level contact of {scheme_name}"
                ),
            ));
        }
        if let Some(reason) = banded_refusal(model, lumped) {
            return Err(SpecError::new("contact_solver.kind", reason));
        }
    }
    let banded = velocity_level && uses_banded(model, lcp.kind, lumped);
    let (n, m) = (model.dofs(), model.contacts.len());
    if !banded && dense_contacts_too_large(n, m) {
        return Err(SpecError::new(
            "model.contacts",
            format!(
                "{m} contacts on {n} dofs need {:.2e} stored entries for the dense operators Ŵ⁻¹G and W = GᵀŴ⁻¹G of contact_solver.kind = {:?}, more than the {:.2e} allowed: single-dof contacts take banded_active_set (or auto) with moreau_jean or the nonsmooth α-family",
                m as f64 * m.max(n) as f64,
                lcp.kind,
                crate::band::MAX_STORED_ENTRIES as f64
            ),
        ));
    }
    Ok(())
}

/// A `lagrangian` model under a scheme of the linear family other than `ns_generalized_alpha`
/// (`lagrangian_ns_alpha`): only `moreau_jean` (the nonlinear Moreau–Jean time-stepping of
/// Acary & Brogliato 2008, ch. 10) can take it, with contacts, joints, friction, or all of them
/// (joints need θ > 0: the scheme refuses θ = 0 naming `integrator.theta`; what the scheme
/// takes is the scheme × feature table's, [`support`]). The model is compiled and checked first,
/// so a bad model is reported before the scheme; joints must be independent and hold at
/// velocity level at the start.
fn lagrangian_moreau_jean(
    m: &ModelSpec,
    l: &LagrangianSpec,
    spec: &JobSpec,
) -> Result<JobKind, SpecError> {
    refuse_redundant_joints(l, spec.integrator.scheme())?;
    let model = UserModel::new(l.validate()?);
    if !matches!(spec.integrator, IntegratorSpec::MoreauJean(_)) {
        return Err(mismatch(m, spec.integrator.scheme()));
    }
    check_joint_start(&model, "moreau_jean", false)?;
    let IntegratorSpec::MoreauJean(p) = &spec.integrator else {
        return Err(mismatch(m, spec.integrator.scheme()));
    };
    // The same θ and index-set checks as the linear scheme.
    let MoreauJeanParams {
        theta, index_set, ..
    } = moreau_jean_params(p, false)?;
    let params = NonlinearMoreauJeanParams {
        theta,
        index_set,
        newton: NewtonOptions::default(),
    };
    let (steps, lcp, output) = lagrangian_run_settings(spec, &model)?;
    // The scheme checks its own parameters once more against the model's sizes.
    // Moreau–Jean's `gamma` is the index set's `activation_gamma`.
    let scheme = NonlinearMoreauJean::new(&model, params, steps.h, lcp).map_err(|e| {
        let field = if e.field == "gamma" {
            "activation_gamma"
        } else {
            e.field
        };
        scheme_field_error(field, e.reason)
    })?;
    Ok(JobKind::Nonlinear(Box::new(NonlinearJob {
        model,
        scheme,
        h: steps.h,
        steps: steps.count(),
        output,
    })))
}

/// The step count, the contact solver and the output of a `lagrangian` job, each checked once.
fn lagrangian_run_settings(
    spec: &JobSpec,
    model: &UserModel,
) -> Result<(Steps, LcpOptions, OutputOptions), SpecError> {
    let steps = spec.time_section()?.steps(support::refusal(
        spec.integrator.scheme(),
        ModelFamily::Lagrangian,
        Feature::VariableStep,
        "",
    ))?;
    let lcp = spec.contact_solver.options()?;
    if lcp.kind == LcpSolverKind::BandedActiveSet {
        return Err(SpecError::new(
            "contact_solver.kind",
            "banded_active_set solves linear models (a banded iteration matrix), not lagrangian ones",
        ));
    }
    let output = spec
        .output
        .options(Probes::Dofs(LagrangianSystem::dofs(model)))?;
    Ok((steps, lcp, output))
}

/// A nonlinear scheme's parameter error as a spec error: `h` is `time.h`, the rest
/// `integrator.<name>`.
fn scheme_field_error(field: &str, reason: String) -> SpecError {
    let field = match field {
        "h" => "time.h".to_string(),
        other => format!("integrator.{other}"),
    };
    SpecError::new(field, reason)
}

/// A `lagrangian` model under `ns_generalized_alpha`: the coefficients and their checks are the
/// linear member's (`rho_inf`, or `alpha_m`, `alpha_f`, `beta`, `gamma`; `allow_unstable`); the
/// index set is the scheme's own (the predicted gap), so `activation` is refused. The start must
/// satisfy the joints at velocity level, with independent joints.
fn lagrangian_ns_alpha(l: &LagrangianSpec, spec: &JobSpec) -> Result<JobKind, SpecError> {
    refuse_redundant_joints(l, spec.integrator.scheme())?;
    let model = UserModel::new(l.validate()?);
    let IntegratorSpec::NsGeneralizedAlpha(p) = &spec.integrator else {
        return Err(SpecError::new(
            "integrator.scheme",
            "only ns_generalized_alpha runs here",
        ));
    };
    if p.index_set != Default::default() {
        return Err(SpecError::new(
            "integrator.activation",
            "a lagrangian model under ns_generalized_alpha takes the contacts whose predicted gap g(q̃_(k+1)) is ≤ 0 (Chen et al. 2013): leave activation and activation_gamma out",
        ));
    }
    let alpha = alpha_params(&spec.integrator)?;
    let params = NsAlphaParams {
        alpha_m: alpha.alpha_m,
        alpha_f: alpha.alpha_f,
        beta: alpha.beta,
        gamma: alpha.gamma,
        newton: NewtonOptions::default(),
        strategy: p.newton.map_or(NewtonStrategy::Full, NewtonStrategy::from),
    };
    refuse_friction(l, spec.integrator.scheme())?;
    check_joint_start(&model, "ns_generalized_alpha", l.redundant_joints)?;
    let (steps, lcp, output) = lagrangian_run_settings(spec, &model)?;
    let scheme = NonsmoothGeneralizedAlpha::new(&model, params, steps.h, lcp)
        .map_err(|e| scheme_field_error(e.field, e.reason))?;
    Ok(JobKind::NsAlpha(Box::new(NsAlphaJob {
        model,
        scheme,
        h: steps.h,
        steps: steps.count(),
        output,
    })))
}

/// Refuses `integrator.newton` on `ns_generalized_alpha` or `ns_kh_alpha` for a model whose
/// step has no Newton iteration (`why`).
fn refuse_newton_strategy(integrator: &IntegratorSpec, why: &str) -> Result<(), SpecError> {
    let newton = match integrator {
        IntegratorSpec::NsGeneralizedAlpha(p) | IntegratorSpec::NsKhAlpha(p) => p.newton,
        _ => None,
    };
    match newton {
        Some(n) => Err(SpecError::new(
            "integrator.newton",
            format!(
                "newton = \"{}\" is not taken by {} here: {why}",
                n.name(),
                integrator.scheme()
            ),
        )),
        None => Ok(()),
    }
}

/// Refuses `redundant_joints = true` under `scheme` when the scheme × feature table does (the
/// fixed-step schemes need g_q of full row rank).
fn refuse_redundant_joints(l: &LagrangianSpec, scheme: &str) -> Result<(), SpecError> {
    if !l.redundant_joints {
        return Ok(());
    }
    support::check(
        scheme,
        ModelFamily::Lagrangian,
        Feature::RedundantJoints,
        "",
    )
}

/// Refuses a `lagrangian` model with Coulomb friction on some contact under `scheme` when the
/// scheme × feature table does ([`support`]): the friction would otherwise be dropped without a
/// word (the run identical to μ = 0, no friction columns).
fn refuse_friction(l: &LagrangianSpec, scheme: &str) -> Result<(), SpecError> {
    let Some((i, mu)) = l
        .contacts
        .iter()
        .enumerate()
        .find_map(|(i, c)| c.friction.filter(|&mu| mu > 0.0).map(|mu| (i, mu)))
    else {
        return Ok(());
    };
    support::check(
        scheme,
        ModelFamily::Lagrangian,
        Feature::Friction,
        &format!("model.contacts[{i}].friction = {mu}"),
    )
}

/// The joints of a user model at its start: G(q0) of full row rank (`model.constraints`), and
/// G(q0) v0 + g_t = 0 to [`crate::lagrangian::JOINT_TOLERANCE`] relative to max(1, ‖G‖‖v0‖)
/// (`model.v0`). `scheme` is named in the refusal of dependent joints; `redundant`
/// (`model.redundant_joints`, for a scheme that solves rank-deficient joints) accepts them.
fn check_joint_start(model: &UserModel, scheme: &str, redundant: bool) -> Result<(), SpecError> {
    let (n, nb) = (LagrangianSystem::dofs(model), JointedSystem::joints(model));
    if nb == 0 {
        return Ok(());
    }
    let (q0, v0) = LagrangianSystem::initial(model);
    let mut g = vec![0.0; nb * n];
    model.joint_jacobian(0.0, &q0, &mut g);
    let gm = nalgebra::DMatrix::from_row_slice(nb, n, &g);
    let Some(sv) = crate::dense::singular_values(gm) else {
        let k = g.iter().position(|x| !x.is_finite()).unwrap_or(0);
        return Err(SpecError::new(
            "model.constraints",
            format!(
                "g_q at q0 is not finite: entry ({}, {}) is {} (constraint {} is undefined there)",
                k / n,
                k % n,
                g[k],
                k / n
            ),
        ));
    };
    let (smax, smin) = (sv.max(), sv.min());
    let independent = nb <= n && smin > 1e-10 * smax;
    if !(independent || redundant && smax.is_finite()) {
        return Err(SpecError::new(
            "model.constraints",
            format!(
                "the joints are not independent at q0 (singular values of g_q from {smax:e} down to {smin:e}): {scheme} needs g_q of full row rank"
            ),
        ));
    }
    let mut r = vec![0.0; nb];
    model.joint_rates(0.0, &q0, &v0, &mut r);
    let size = smax * v0.iter().fold(1.0f64, |m, x| m.max(x.abs()));
    let worst = r.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if worst > crate::lagrangian::JOINT_TOLERANCE * size {
        return Err(SpecError::new(
            "model.v0",
            format!(
                "the joints are violated at velocity level: |g_q v0 + g_t| = {worst:e} (tolerance {:e})",
                crate::lagrangian::JOINT_TOLERANCE * size
            ),
        ));
    }
    Ok(())
}

impl Job {
    /// Validates `spec` and builds the job. Every error names the offending field. The job's
    /// kind follows from the sections: an `[analysis]`, or the pair (scene, scheme family).
    pub fn from_spec(spec: &JobSpec) -> Result<Job, SpecError> {
        if let Some(check) = &spec.check {
            check.validate()?;
            if check.min_order.is_some() {
                return Err(SpecError::new(
                    "check.min_order",
                    "an observed order needs a study of several step sizes; this spec is one run",
                ));
            }
        }
        if spec.study.is_some() {
            return Err(SpecError::new(
                "study",
                "a study is several runs, not one job: run it with `signorini run STUDY.toml`, \
                 or submit it to the service, which runs each as a child job",
            ));
        }
        let model = spec.model.as_ref();
        let kind = match (&spec.analysis, model, spec.integrator.family()) {
            // An analysis describes its own bar: a model next to it would be silently ignored.
            (Some(_), Some(_), _) => {
                return Err(SpecError::new(
                    "analysis",
                    "`model` and `analysis` together: an analysis describes its own bar, so give either `model` (with `time`) or `analysis`",
                ));
            }
            (Some(analysis), None, _) => JobKind::Wave(Box::new(wave::analysis(analysis)?)),
            (None, None, _) => return Err(SpecError::new("model", "missing section")),
            (None, Some(ModelSpec::RigidBodies(r)), _) => {
                JobKind::Rigid(Box::new(rigid::rigid_job(r, spec)?))
            }
            (None, Some(m), SchemeFamily::Wave) => {
                JobKind::Wave(Box::new(wave::integration(m, spec)?))
            }
            (None, Some(m @ ModelSpec::Lagrangian(_)), SchemeFamily::Soi2) => {
                JobKind::Soi2(Box::new(soi2::soi2_job(m, spec)?))
            }
            (None, Some(ModelSpec::Lagrangian(l)), SchemeFamily::Linear)
                if matches!(spec.integrator, IntegratorSpec::NsGeneralizedAlpha(_)) =>
            {
                lagrangian_ns_alpha(l, spec)?
            }
            (None, Some(m @ ModelSpec::Lagrangian(l)), SchemeFamily::Linear) => {
                lagrangian_moreau_jean(m, l, spec)?
            }
            (None, Some(m), SchemeFamily::Soi2) if m.is_constrained() => {
                JobKind::Soi2(Box::new(soi2::soi2_job(m, spec)?))
            }
            (None, Some(m), SchemeFamily::Linear) if !m.is_constrained() => {
                JobKind::Linear(Box::new(LinearJob::from_spec(m, spec)?))
            }
            (None, Some(m), _) => return Err(mismatch(m, spec.integrator.scheme())),
        };
        if !matches!(kind, JobKind::Rigid(_)) {
            for (field, asked) in [
                ("output.contacts", spec.output.contacts),
                ("output.vtk", spec.output.vtk),
            ] {
                if asked {
                    return Err(SpecError::new(
                        field,
                        "only a `rigid_bodies` job has contact points and bodies to write",
                    ));
                }
            }
            if spec.contact_solver.accept_error.is_some() {
                return Err(SpecError::new(
                    "contact_solver.accept_error",
                    "only a `rigid_bodies` step accepts a friction problem solved above the \
                     tolerance; this job's steps solve their contact problems to the tolerance \
                     or fail",
                ));
            }
        }
        // The model validated once more for its report: its start projection, when it asks
        // for one (parsing and checks only, no tapes).
        let start = match model {
            Some(ModelSpec::Lagrangian(l)) if l.project_onto_joints => l.validate()?.projection,
            _ => None,
        };
        Ok(Job {
            spec: spec.clone(),
            kind,
            start,
        })
    }

    /// How the start of a `lagrangian` model was moved onto its joints
    /// (`model.project_onto_joints`), as the summary reports it (`start_projection`).
    pub fn start_projection(&self) -> Option<&StartProjection> {
        self.start.as_ref()
    }

    /// The spec this job was built from.
    pub fn spec(&self) -> &JobSpec {
        &self.spec
    }

    /// The hash of this job's spec that its checkpoints carry ([`spec_hash`]).
    pub fn spec_hash(&self) -> u64 {
        spec_hash(&self.spec)
    }

    /// Reads a checkpoint written by a run of this job's spec; refuses foreign, damaged or
    /// mismatched bytes with the reason ([`Checkpoint::decode`]).
    pub fn read_checkpoint(&self, bytes: &[u8]) -> Result<Checkpoint, CheckpointError> {
        Checkpoint::decode(bytes, self.spec_hash())
    }

    /// Whether a run of this job hands checkpoints to an observer that asks for them: every time
    /// integration does (the banded contact path and the contact-region chart included: the
    /// solver's warm start and the chart's grid are in the checkpoint); an analysis of modes or
    /// forced response reruns whole.
    pub fn checkpoints(&self) -> bool {
        match &self.kind {
            JobKind::Wave(j) => !j.is_analysis(),
            _ => true,
        }
    }

    /// True when the run draws the `contact_region` chart: its time buckets are sized by the
    /// run's length, so such a run cannot be continued to a later end with the same chart.
    pub fn draws_contact_region(&self) -> bool {
        matches!(&self.kind, JobKind::Linear(j) if j.region.is_some())
    }

    /// Size of the job.
    pub fn size(&self) -> JobSize {
        match &self.kind {
            JobKind::Wave(j) => {
                let (dofs, steps) = j.size();
                JobSize {
                    dofs,
                    steps,
                    output_bytes: steps.saturating_add(2).saturating_mul(24 * 8),
                }
            }
            JobKind::Soi2(j) => {
                let steps = j.steps();
                let recorded = steps / j.output.every.max(1) + 2;
                JobSize {
                    dofs: j.dofs() as u64,
                    steps,
                    output_bytes: recorded.saturating_mul((j.columns() as u64 + 2) * 8),
                }
            }
            JobKind::Linear(j) => {
                let recorded = j.steps / j.output.every.max(1) + 2;
                let per_contact = if j.model.has_friction() { 5 } else { 3 };
                let friction = if j.model.has_friction() { 2 } else { 0 };
                let columns = 12
                    + friction
                    + per_contact * j.model.contacts.len()
                    + 2 * j.output.probes.len()
                    + 2;
                JobSize {
                    dofs: j.model.dofs() as u64,
                    steps: j.steps,
                    output_bytes: recorded.saturating_mul(columns as u64 * 8),
                }
            }
            JobKind::Nonlinear(j) => {
                let recorded = j.steps / j.output.every.max(1) + 2;
                let contacts = LagrangianSystem::contacts(&j.model);
                // The run's columns, plus step and t.
                let friction = has_friction(&j.model);
                let joints = JointedSystem::joints(&j.model) > 0;
                let columns =
                    nonlinear_columns(contacts, friction, joints, &j.output.probes).len() + 2;
                JobSize {
                    dofs: LagrangianSystem::dofs(&j.model) as u64,
                    steps: j.steps,
                    output_bytes: recorded.saturating_mul(columns as u64 * 8),
                }
            }
            JobKind::Rigid(j) => {
                let recorded = j.steps / j.every.max(1) + 2;
                JobSize {
                    dofs: 6 * j.scene.bodies.len() as u64,
                    steps: j.steps,
                    output_bytes: recorded.saturating_mul(j.columns() as u64 * 8),
                }
            }
            JobKind::NsAlpha(j) => {
                let recorded = j.steps / j.output.every.max(1) + 2;
                let columns = ns_alpha_columns(
                    LagrangianSystem::contacts(&j.model),
                    has_friction(&j.model),
                    JointedSystem::joints(&j.model),
                    &j.output.probes,
                )
                .len()
                    + 2;
                JobSize {
                    dofs: LagrangianSystem::dofs(&j.model) as u64,
                    steps: j.steps,
                    output_bytes: recorded.saturating_mul(columns as u64 * 8),
                }
            }
        }
    }
}

/// Runs a validated job to the end (or until the observer stops it). A run that records steps
/// also returns the charts `energy` and `residuals` of its records ([`EnergyTrace`]).
///
/// `threads` is the parallelism the caller grants: an analysis (nonsmooth modes, forced
/// response) spreads its independent tasks over that many threads (0 counts as 1), a time
/// integration runs on the calling thread. The results do not depend on it.
pub fn run(job: &Job, threads: usize, observer: &mut dyn Observer) -> Result<RunOutput, RunError> {
    run_from(job, threads, observer, None, None)
}

/// [`run`] or, with a checkpoint, [`resume`], with the contact detectors a `rigid_bodies` job
/// needs (the core defines the trait; the binary gives parry's, `signorini-collision`). Other
/// jobs ignore `detectors`; a `rigid_bodies` job run without them fails with
/// [`RunError::NoDetector`].
pub fn run_with_detectors(
    job: &Job,
    threads: usize,
    observer: &mut dyn Observer,
    checkpoint: Option<&Checkpoint>,
    detectors: &dyn DetectorFactory,
) -> Result<RunOutput, RunError> {
    run_from(job, threads, observer, checkpoint, Some(detectors))
}

/// Continues a run of `job` from `checkpoint` (read by [`Job::read_checkpoint`]): the steps
/// after it are computed exactly as an uninterrupted run computes them, and `observer` receives
/// the records after the checkpoint's [`Checkpoint::records`] first ones (it is
/// [`Observer::start`]ed again, with the same columns, but gets no initial record). The output
/// (summary, charts, every recorded value) equals the uninterrupted run's bit for bit. A
/// checkpoint of another kind of run, or whose state does not fit the model, is refused before
/// any step ([`RunError::Checkpoint`]).
pub fn resume(
    job: &Job,
    threads: usize,
    observer: &mut dyn Observer,
    checkpoint: &Checkpoint,
) -> Result<RunOutput, RunError> {
    run_from(job, threads, observer, Some(checkpoint), None)
}

fn run_from(
    job: &Job,
    threads: usize,
    observer: &mut dyn Observer,
    checkpoint: Option<&Checkpoint>,
    detectors: Option<&dyn DetectorFactory>,
) -> Result<RunOutput, RunError> {
    if let Some(c) = checkpoint
        && c.spec_hash() != job.spec_hash()
    {
        return Err(CheckpointError::Spec {
            expected: job.spec_hash(),
            found: c.spec_hash(),
        }
        .into());
    }
    let records = checkpoint.map_or(0, Checkpoint::records);
    let trace_state = checkpoint
        .map(Checkpoint::trace_state)
        .transpose()?
        .flatten();
    let mut stamp = Stamp {
        inner: observer,
        spec_hash: job.spec_hash(),
        records,
    };
    let mut trace = EnergyTrace::resumed(&mut stamp, trace_state);
    // A user's own model gets figures of what it does (its probed coordinates, gaps and
    // impulses) besides the energy and the checks.
    if matches!(job.spec().model, Some(ModelSpec::Lagrangian(_))) {
        trace = trace.with_motion();
    }
    let t = &mut trace;
    let c = checkpoint;
    let mut output = match &job.kind {
        JobKind::Linear(j) => run_linear_job(job, j, t, c),
        JobKind::Soi2(j) => run_soi2_job(job, j, t, c),
        JobKind::Wave(j) => j.run_from(header(job), threads, t, c),
        JobKind::Nonlinear(j) => run_nonlinear_job(job, j, t, c),
        JobKind::NsAlpha(j) => run_ns_alpha_job(job, j, t, c),
        JobKind::Rigid(j) => j.run_from(t, c, detectors).map(|(body, tables)| RunOutput {
            summary: RunSummary::new(header(job), body),
            tables,
            charts: Vec::new(),
        }),
    }?;
    output.charts.extend(trace.charts());
    output.summary.start_projection = job.start.clone();
    Ok(output)
}

/// The observer between a run (and its [`EnergyTrace`]) and the caller's: counts the records
/// handed out and stamps the count and the spec hash on every checkpoint.
struct Stamp<'a> {
    inner: &'a mut dyn Observer,
    spec_hash: u64,
    records: u64,
}

impl Observer for Stamp<'_> {
    fn start(&mut self, columns: &Columns) {
        self.inner.start(columns);
    }

    fn observe(&mut self, record: &StepRecord<'_>) -> ControlFlow<()> {
        self.records += 1;
        self.inner.observe(record)
    }

    fn progress(&mut self, progress: Progress) -> ControlFlow<()> {
        self.inner.progress(progress)
    }

    fn checkpoint_due(&mut self, progress: Progress) -> bool {
        self.inner.checkpoint_due(progress)
    }

    fn checkpoint(&mut self, checkpoint: &mut Checkpoint) {
        checkpoint.stamp(self.records, self.spec_hash);
        self.inner.checkpoint(checkpoint);
    }
}

/// The hash a checkpoint of `spec` carries: FNV-1a 64 of the spec's JSON with the checkpoint
/// period and the run's end (`time.t_end`, `time.steps`) left out: a run may be resumed with
/// another period, and a run's state after step k does not depend on where the run ends, so a
/// checkpoint may be continued to a later end (the service's `extend`) and continue bit for
/// bit. Every other field is hashed: a checkpoint of another model, scheme, step size or output
/// is refused.
pub fn spec_hash(spec: &JobSpec) -> u64 {
    let mut spec = spec.clone();
    spec.output.checkpoint_seconds = None;
    spec.output.checkpoint_steps = None;
    if let Some(time) = spec.time.as_mut() {
        time.t_end = None;
        time.steps = None;
    }
    // A JobSpec is plain data (no map with non-string keys): its JSON always serialises.
    let json = serde_json::to_vec(&spec).unwrap_or_default();
    crate::checkpoint::fnv1a(&json)
}

fn run_nonlinear_job(
    job: &Job,
    j: &NonlinearJob,
    observer: &mut dyn Observer,
    resume: Option<&Checkpoint>,
) -> Result<RunOutput, RunError> {
    let mut scheme = j.scheme.clone();
    let mut state = NonlinearState::initial(&j.model);
    let stats = run_user_model(
        &j.model,
        &mut scheme,
        &mut state,
        j.steps,
        &j.output,
        observer,
        resume,
    )?;
    let body = SummaryBody::Nonlinear(NonlinearSummary {
        dofs: LagrangianSystem::dofs(&j.model),
        contacts: LagrangianSystem::contacts(&j.model),
        h: j.h,
        stats,
    });
    Ok(RunOutput {
        summary: RunSummary::new(header(job), body),
        tables: Vec::new(),
        charts: Vec::new(),
    })
}

fn run_ns_alpha_job(
    job: &Job,
    j: &NsAlphaJob,
    observer: &mut dyn Observer,
    resume: Option<&Checkpoint>,
) -> Result<RunOutput, RunError> {
    let mut scheme = j.scheme.clone();
    let mut state = NonlinearState::initial(&j.model);
    let stats = run_user_model(
        &j.model,
        &mut scheme,
        &mut state,
        j.steps,
        &j.output,
        observer,
        resume,
    )?;
    let p = scheme.params();
    let body = SummaryBody::NsAlpha(Box::new(NsAlphaSummary {
        dofs: LagrangianSystem::dofs(&j.model),
        contacts: LagrangianSystem::contacts(&j.model),
        joints: JointedSystem::joints(&j.model),
        h: j.h,
        alpha_m: p.alpha_m,
        alpha_f: p.alpha_f,
        beta: p.beta,
        gamma: p.gamma,
        stats,
    }));
    Ok(RunOutput {
        summary: RunSummary::new(header(job), body),
        tables: Vec::new(),
        charts: Vec::new(),
    })
}

fn run_soi2_job(
    job: &Job,
    j: &crate::soi2::run::Soi2Job,
    observer: &mut dyn Observer,
    resume: Option<&Checkpoint>,
) -> Result<RunOutput, RunError> {
    let body = SummaryBody::Soi2(Box::new(j.run_from(observer, resume)?));
    Ok(RunOutput {
        summary: RunSummary::new(header(job), body),
        tables: Vec::new(),
        charts: Vec::new(),
    })
}

fn run_linear_job(
    job: &Job,
    j: &LinearJob,
    observer: &mut dyn Observer,
    resume: Option<&Checkpoint>,
) -> Result<RunOutput, RunError> {
    let mut scheme: Box<dyn LinearScheme> = match j.scheme {
        LinearSchemeChoice::MoreauJean(p) => {
            Box::new(MoreauJean::new(&j.model, p, j.h, j.lcp).map_err(RunError::IterationMatrix)?)
        }
        LinearSchemeChoice::Alpha(p) => Box::new(
            NonsmoothAlpha::new(&j.model, p, j.h, j.lcp).map_err(RunError::IterationMatrix)?,
        ),
        LinearSchemeChoice::PositionContact(p) => Box::new(
            PositionContact::new(&j.model, p, j.h, j.lcp).map_err(RunError::IterationMatrix)?,
        ),
    };
    let mut state = LinearState::initial(&j.model);
    let (stats, charts) = match &j.region {
        Some(r) => {
            let records = j.steps / j.output.every.max(1) + 2;
            let mut region = ContactRegion::new(observer, r.first, r.x.clone(), r.delta, records);
            if let Some(state) = resume.map(Checkpoint::region_state).transpose()?.flatten() {
                region.restore(state)?;
            } else if resume.is_some() {
                return Err(CheckpointError::Mismatch(
                    "a checkpoint without the contact-region grid, this job draws one".into(),
                )
                .into());
            }
            let stats = run_linear_from(
                &j.model,
                scheme.as_mut(),
                &mut state,
                j.steps,
                &j.output,
                &mut region,
                resume,
            )?;
            (stats, vec![region.chart()])
        }
        None => (
            run_linear_from(
                &j.model,
                scheme.as_mut(),
                &mut state,
                j.steps,
                &j.output,
                observer,
                resume,
            )?,
            Vec::new(),
        ),
    };
    let body = SummaryBody::Linear(LinearSummary {
        dofs: j.model.dofs(),
        contacts: j.model.contacts.len(),
        h: j.h,
        stats,
    });
    Ok(RunOutput {
        summary: RunSummary::new(header(job), body),
        tables: Vec::new(),
        charts,
    })
}

fn header(job: &Job) -> SummaryHeader {
    SummaryHeader {
        name: job.spec.name.clone(),
        scene: job.spec.model.as_ref().map(|m| m.scene().to_string()),
        scheme: match job.spec.analysis {
            Some(_) => None,
            None => Some(job.spec.integrator.scheme().to_string()),
        },
        analysis: job.spec.analysis.as_ref().map(|a| a.kind().to_string()),
    }
}

/// Builds the linear model of a scene; errors carry `model.`-prefixed fields.
pub fn build_model(spec: &ModelSpec) -> Result<LinearModel, SpecError> {
    let result = match spec {
        ModelSpec::BouncingBall(b) => b.build(),
        ModelSpec::Bar(b) => b.resolve(Bar::default()).build_with(b.obstacle.as_ref()),
        ModelSpec::DepBar(b) => b
            .resolve(Bar::doyen_ern_piperno(100))
            .build_with(b.obstacle.as_ref()),
        ModelSpec::Chain(c) => c.build(),
        ModelSpec::String(st) => st.build(),
        ModelSpec::Linear(l) => build_linear(l),
        ModelSpec::Pendulum(_)
        | ModelSpec::SliderCrank(_)
        | ModelSpec::JayNegrutTest(_)
        | ModelSpec::Lagrangian(_)
        | ModelSpec::RigidBodies(_) => {
            return Err(mismatch(spec, "a linear scheme"));
        }
    };
    result.map_err(|e| SpecError::new(format!("model.{}", e.field()), e.reason()))
}

fn matrix(
    name: &str,
    rows: &Option<Vec<Vec<f64>>>,
    triplets: &Option<Vec<(usize, usize, f64)>>,
    n: usize,
) -> Result<SymBand, ModelError> {
    let tname = format!("{name}_triplets");
    match (rows, triplets) {
        (Some(_), Some(_)) => Err(ModelError::OutOfRange {
            field: name.into(),
            value: 0.0,
            range: "one spelling: give the dense rows or the triplets, not both",
        }),
        (Some(r), None) => {
            let m = SymBand::from_dense_rows(r).map_err(|source| ModelError::Matrix {
                field: name.into(),
                source,
            })?;
            if m.n() != n {
                return Err(ModelError::Dimension {
                    field: name.into(),
                    expected: n,
                    found: m.n(),
                });
            }
            Ok(m)
        }
        (None, Some(t)) => SymBand::from_triplets(n, t).map_err(|source| ModelError::Matrix {
            field: tname,
            source,
        }),
        (None, None) => Ok(SymBand::zeros(n, 0)),
    }
}

fn build_linear(l: &LinearSpec) -> Result<LinearModel, ModelError> {
    // The order n comes from the mass matrix.
    let n = match (&l.mass, &l.mass_triplets) {
        (Some(r), _) => r.len(),
        (None, Some(t)) => t.iter().map(|&(i, j, _)| i.max(j) + 1).max().unwrap_or(0),
        (None, None) => {
            return Err(ModelError::Dimension {
                field: "mass".into(),
                expected: 1,
                found: 0,
            });
        }
    };
    if n == 0 {
        return Err(ModelError::Dimension {
            field: "mass".into(),
            expected: 1,
            found: 0,
        });
    }
    let mass = matrix("mass", &l.mass, &l.mass_triplets, n)?;
    let stiffness = matrix("stiffness", &l.stiffness, &l.stiffness_triplets, n)?;
    let damping = matrix("damping", &l.damping, &l.damping_triplets, n)?;
    let m = l.g_matrix.len();
    let offsets = l.g_offset.clone().unwrap_or_else(|| vec![0.0; m]);
    crate::model::check_vector("g_offset", &offsets, m)?;
    crate::model::check_vector("restitution", &l.restitution, m)?;
    let mut contacts = Vec::with_capacity(m);
    for (a, row) in l.g_matrix.iter().enumerate() {
        crate::model::check_vector(&format!("g_matrix[{a}]"), row, n)?;
        contacts.push(Contact {
            g: row
                .iter()
                .enumerate()
                .filter(|(_, c)| **c != 0.0)
                .map(|(i, &c)| (i, c))
                .collect(),
            offset: offsets[a],
            motion: None,
            restitution: l.restitution[a],
        });
    }
    let force = Forcing {
        constant: l.force.clone().unwrap_or_else(|| vec![0.0; n]),
        harmonic: l
            .harmonic_force
            .iter()
            .map(|h| HarmonicLoad {
                shape: h.shape.clone(),
                omega: h.omega,
                phase: h.phase,
            })
            .collect(),
    };
    let model = LinearModel::new(
        mass,
        damping,
        stiffness,
        force,
        contacts,
        l.q0.clone().unwrap_or_else(|| vec![0.0; n]),
        l.v0.clone().unwrap_or_else(|| vec![0.0; n]),
    );
    // Contact rows are validated by LinearModel with `contacts[α]`; the spec calls them g_matrix.
    let model = model.map_err(|e| match e {
        ModelError::OutOfRange {
            field,
            value,
            range,
        } if field.starts_with("contacts[") => {
            let field = field
                .replace("contacts", "g_matrix")
                .replace(".g", "")
                .replace(".restitution", "");
            ModelError::OutOfRange {
                field,
                value,
                range,
            }
        }
        other => other,
    })?;
    linear_friction(l, model, n, m)
}

/// The Coulomb friction of a `linear` model: `friction` (μ per contact, zero when absent) and
/// `t_matrix` (one tangent row per contact), required when some μ > 0.
fn linear_friction(
    l: &LinearSpec,
    model: LinearModel,
    n: usize,
    m: usize,
) -> Result<LinearModel, ModelError> {
    let mu = match (&l.friction, &l.t_matrix) {
        (None, None) => return Ok(model),
        (Some(mu), _) => mu.clone(),
        (None, Some(_)) => vec![0.0; m],
    };
    crate::model::check_vector("friction", &mu, m)?;
    let rows = match &l.t_matrix {
        Some(rows) => {
            crate::model::check_vector("t_matrix", &vec![0.0; rows.len()], m)?;
            for (a, row) in rows.iter().enumerate() {
                crate::model::check_vector(&format!("t_matrix[{a}]"), row, n)?;
            }
            rows.clone()
        }
        None if mu.iter().all(|&x| x == 0.0) => vec![vec![0.0; n]; m],
        None => {
            return Err(ModelError::Required {
                field: "t_matrix".into(),
                reason: "required when friction > 0 (one tangent row per contact)",
            });
        }
    };
    let friction = rows
        .iter()
        .zip(&mu)
        .map(|(row, &mu)| ContactFriction {
            t: row
                .iter()
                .enumerate()
                .filter(|(_, c)| **c != 0.0)
                .map(|(i, &c)| (i, c))
                .collect(),
            mu,
        })
        .collect();
    model.with_friction(friction)
}

fn moreau_jean_params(p: &MoreauJeanSpec, variant: bool) -> Result<MoreauJeanParams, SpecError> {
    if !p.theta.is_finite() || !(0.0..=1.0).contains(&p.theta) {
        return Err(SpecError::new(
            "integrator.theta",
            format!("must be in [0, 1], got {}", p.theta),
        ));
    }
    Ok(MoreauJeanParams {
        theta: p.theta,
        variant,
        index_set: p.index_set.rule()?,
    })
}
/// The outcome of a scheme's parameter check (`validate`), with `allow_unstable`: a stability
/// condition may be waived, any other error (a parameter outside its domain) may not. Errors
/// name `integrator.<field>`.
fn stability_checked(check: Result<(), ParamError>, allow_unstable: bool) -> Result<(), SpecError> {
    match check {
        Ok(()) => Ok(()),
        Err(ParamError {
            stability: true, ..
        }) if allow_unstable => Ok(()),
        Err(e) => {
            let hint = if e.stability {
                " (set allow_unstable = true to run it anyway)"
            } else {
                ""
            };
            Err(SpecError::new(
                format!("integrator.{}", e.field),
                format!("{}{hint}", e.reason),
            ))
        }
    }
}

/// Parameters of `ns_generalized_alpha` / `ns_kh_alpha` from ρ∞ (26)–(27) or given directly.
fn ns_alpha_from_spec(p: &NsAlphaSpec, scheme: AlphaScheme) -> Result<AlphaParams, SpecError> {
    let p = &p.coefficients;
    let direct = [
        ("alpha_m", p.alpha_m),
        ("alpha_f", p.alpha_f),
        ("beta", p.beta),
        ("gamma", p.gamma),
    ];
    if let Some(rho) = p.rho_inf {
        if let Some((f, _)) = direct.iter().find(|(_, x)| x.is_some()) {
            return Err(SpecError::new(
                format!("integrator.{f}"),
                "give rho_inf or alpha_m/alpha_f/beta/gamma, not both",
            ));
        }
        if !rho.is_finite() || !(0.0..=1.0).contains(&rho) {
            return Err(SpecError::new(
                "integrator.rho_inf",
                format!("must be in [0, 1], got {rho}"),
            ));
        }
        return Ok(AlphaParams::from_rho_inf(scheme, rho));
    }
    match (p.alpha_m, p.alpha_f) {
        (None, None) if p.beta.is_none() && p.gamma.is_none() => {
            Ok(AlphaParams::from_rho_inf(scheme, 0.8))
        }
        (Some(alpha_m), Some(alpha_f)) => {
            let gamma = p.gamma.unwrap_or(0.5 + alpha_f - alpha_m);
            let beta = p.beta.unwrap_or(0.25 * (gamma + 0.5) * (gamma + 0.5));
            Ok(AlphaParams {
                scheme,
                alpha_m,
                alpha_f,
                beta,
                gamma,
                index_set: IndexSetRule::default(),
            })
        }
        (None, _) => Err(SpecError::new(
            "integrator.alpha_m",
            "missing: give rho_inf, or alpha_m and alpha_f",
        )),
        (_, None) => Err(SpecError::new(
            "integrator.alpha_f",
            "missing: give rho_inf, or alpha_m and alpha_f",
        )),
    }
}

/// Validated parameters of an `ns_*` integrator spec.
fn alpha_params(spec: &IntegratorSpec) -> Result<AlphaParams, SpecError> {
    let (mut params, index_set, allow_unstable) = match spec {
        IntegratorSpec::NsNewmark(p) => (
            AlphaParams::newmark(p.beta, p.gamma),
            p.index_set,
            p.allow_unstable,
        ),
        IntegratorSpec::NsHht(p) => {
            let gamma = p.gamma.unwrap_or(0.5 + p.alpha);
            let beta = p.beta.unwrap_or(0.25 * (1.0 + p.alpha) * (1.0 + p.alpha));
            (
                AlphaParams::hht_with(p.alpha, beta, gamma),
                p.index_set,
                p.allow_unstable,
            )
        }
        IntegratorSpec::NsGeneralizedAlpha(p) => (
            ns_alpha_from_spec(p, AlphaScheme::GeneralizedAlpha)?,
            p.index_set,
            p.allow_unstable,
        ),
        IntegratorSpec::NsKhAlpha(p) => (
            ns_alpha_from_spec(p, AlphaScheme::KrenkHogsberg)?,
            p.index_set,
            p.allow_unstable,
        ),
        other => unreachable!("alpha_params called for {}", other.scheme()),
    };
    params.index_set = index_set.rule()?;
    stability_checked(params.validate(), allow_unstable)?;
    Ok(params)
}

/// Validated parameters of `newmark_position_contact` (`hht = false`) or `hht_position_contact`.
fn position_contact_params(
    p: &PositionContactSpec,
    hht: bool,
) -> Result<PositionContactParams, SpecError> {
    let params = match (hht, p.alpha) {
        (false, Some(_)) => {
            return Err(SpecError::new(
                "integrator.alpha",
                "newmark_position_contact has no α (use hht_position_contact)",
            ));
        }
        (false, None) => {
            PositionContactParams::newmark(p.beta.unwrap_or(0.25), p.gamma.unwrap_or(0.5))
        }
        (true, None) => {
            return Err(SpecError::new(
                "integrator.alpha",
                "missing: hht_position_contact needs α",
            ));
        }
        (true, Some(alpha)) => {
            let d = PositionContactParams::hht(alpha);
            PositionContactParams {
                alpha,
                beta: p.beta.unwrap_or(d.beta),
                gamma: p.gamma.unwrap_or(d.gamma),
            }
        }
    };
    stability_checked(params.validate(), p.allow_unstable)?;
    Ok(params)
}
