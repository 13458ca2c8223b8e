//! Conversions at the gRPC edge: proto messages → the core's `JobSpec` (one domain type), and
//! the service's views → proto. Every proto message is destructured field by field, so a field
//! added to the `.proto` breaks the build here until it is handled. These conversions only move
//! data; validation happens once, in `Job::from_spec` (a missing required field is reported with
//! its path, like serde does for JSON and TOML).

use crate::proto::v1 as pb;
use crate::store::{JobState, StoredResult};
use crate::worker::JobView;
use signorini_core::contact::Activation;
use signorini_core::lcp::LcpSolverKind;
use signorini_core::scenes::{BarSpec, BouncingBall, Chain, HarmonicSpec, LeftEnd, MassMatrix};
use signorini_core::spec::{
    ContactSolverSpec, HarmonicForceSpec, IntegratorSpec, JobSpec, LinearSpec, ModelSpec,
    MoreauJeanSpec, OutputSpec, SpecError, TimeSpec,
};

fn usize_of(field: &str, v: u64) -> Result<usize, SpecError> {
    usize::try_from(v).map_err(|_| SpecError::new(field, format!("{v} is too large")))
}

/// A typed proto spec → the core spec.
pub fn job_spec(p: pb::JobSpec) -> Result<JobSpec, SpecError> {
    let pb::JobSpec {
        name,
        model,
        integrator,
        time,
        contact_solver,
        output,
    } = p;
    Ok(JobSpec {
        name,
        model: model.map(model_spec).transpose()?,
        integrator: integrator
            .map(integrator_spec)
            .transpose()?
            .unwrap_or_default(),
        time: time.map(time_spec).transpose()?,
        contact_solver: contact_solver
            .map(contact_solver_spec)
            .transpose()?
            .unwrap_or_default(),
        output: output.map(output_spec).transpose()?.unwrap_or_default(),
        // Analyses (nonsmooth modes, forced response) travel in the JSON spelling for now.
        analysis: None,
    })
}

fn model_spec(p: pb::ModelSpec) -> Result<ModelSpec, SpecError> {
    use pb::model_spec::Scene;
    let pb::ModelSpec { scene } = p;
    Ok(
        match scene.ok_or_else(|| SpecError::new("model.scene", "missing: choose a scene"))? {
            Scene::BouncingBall(b) => ModelSpec::BouncingBall(bouncing_ball(b)),
            Scene::Bar(b) => ModelSpec::Bar(bar(b)?),
            Scene::DepBar(b) => ModelSpec::DepBar(bar(b)?),
            Scene::Chain(c) => ModelSpec::Chain(chain(c)),
            Scene::Linear(l) => ModelSpec::Linear(linear(l)?),
        },
    )
}

fn bouncing_ball(p: pb::BouncingBall) -> BouncingBall {
    let pb::BouncingBall {
        mass,
        gravity,
        q0,
        v0,
        restitution,
    } = p;
    let d = BouncingBall::default();
    BouncingBall {
        mass: mass.unwrap_or(d.mass),
        gravity: gravity.unwrap_or(d.gravity),
        q0: q0.unwrap_or(d.q0),
        v0: v0.unwrap_or(d.v0),
        restitution: restitution.unwrap_or(d.restitution),
    }
}

fn harmonic(p: pb::Harmonic) -> HarmonicSpec {
    let pb::Harmonic { amplitude, omega } = p;
    HarmonicSpec { amplitude, omega }
}

fn bar(p: pb::BarModel) -> Result<BarSpec, SpecError> {
    let pb::BarModel {
        elements,
        length,
        young,
        density,
        area,
        mass_matrix,
        left,
        gap,
        restitution,
        initial_velocity,
        initial_displacement,
        body_force,
        rayleigh_mass,
        rayleigh_stiffness,
        harmonic_force,
        wall_motion,
    } = p;
    let mass_matrix = match pb::MassMatrix::try_from(mass_matrix) {
        Ok(pb::MassMatrix::Unspecified) => None,
        Ok(pb::MassMatrix::Lumped) => Some(MassMatrix::Lumped),
        Ok(pb::MassMatrix::Consistent) => Some(MassMatrix::Consistent),
        Err(_) => {
            return Err(SpecError::new(
                "model.mass_matrix",
                format!("unknown value {mass_matrix}"),
            ));
        }
    };
    let left = match pb::LeftEnd::try_from(left) {
        Ok(pb::LeftEnd::Unspecified) => None,
        Ok(pb::LeftEnd::Fixed) => Some(LeftEnd::Fixed),
        Ok(pb::LeftEnd::Free) => Some(LeftEnd::Free),
        Err(_) => {
            return Err(SpecError::new(
                "model.left",
                format!("unknown value {left}"),
            ));
        }
    };
    Ok(BarSpec {
        elements: elements
            .map(|e| usize_of("model.elements", e))
            .transpose()?,
        length,
        young,
        density,
        area,
        mass_matrix,
        left,
        gap,
        restitution,
        initial_velocity,
        initial_displacement,
        body_force,
        rayleigh_mass,
        rayleigh_stiffness,
        harmonic_force: harmonic_force.map(harmonic),
        wall_motion: wall_motion.map(harmonic),
    })
}

fn chain(p: pb::ChainModel) -> Chain {
    let pb::ChainModel {
        masses,
        stiffness,
        positions,
        velocities,
        wall,
        restitution,
        force,
    } = p;
    let d = Chain::default();
    let or_default = |v: Vec<f64>, d: Vec<f64>| if v.is_empty() { d } else { v };
    Chain {
        masses: or_default(masses, d.masses),
        stiffness: stiffness.unwrap_or(d.stiffness),
        positions: or_default(positions, d.positions),
        velocities: or_default(velocities, d.velocities),
        wall: wall.unwrap_or(d.wall),
        restitution: restitution.unwrap_or(d.restitution),
        force: if force.is_empty() {
            d.force
        } else {
            Some(force)
        },
    }
}

fn dense(p: pb::DenseMatrix) -> Vec<Vec<f64>> {
    let pb::DenseMatrix { rows } = p;
    rows.into_iter()
        .map(|r| {
            let pb::Row { values } = r;
            values
        })
        .collect()
}

type Triplets = Vec<(usize, usize, f64)>;

fn triplets(field: &str, v: Vec<pb::Triplet>) -> Result<Option<Triplets>, SpecError> {
    if v.is_empty() {
        return Ok(None);
    }
    v.into_iter()
        .map(|t| {
            let pb::Triplet { row, col, value } = t;
            Ok((usize_of(field, row)?, usize_of(field, col)?, value))
        })
        .collect::<Result<Vec<_>, _>>()
        .map(Some)
}

fn some_if_nonempty(v: Vec<f64>) -> Option<Vec<f64>> {
    if v.is_empty() { None } else { Some(v) }
}

fn linear(p: pb::LinearModel) -> Result<LinearSpec, SpecError> {
    let pb::LinearModel {
        mass,
        mass_triplets,
        stiffness,
        stiffness_triplets,
        damping,
        damping_triplets,
        force,
        harmonic_force,
        g_matrix,
        g_offset,
        restitution,
        q0,
        v0,
    } = p;
    Ok(LinearSpec {
        mass: mass.map(dense),
        mass_triplets: triplets("model.mass_triplets", mass_triplets)?,
        stiffness: stiffness.map(dense),
        stiffness_triplets: triplets("model.stiffness_triplets", stiffness_triplets)?,
        damping: damping.map(dense),
        damping_triplets: triplets("model.damping_triplets", damping_triplets)?,
        force: some_if_nonempty(force),
        harmonic_force: harmonic_force
            .into_iter()
            .map(|h| {
                let pb::HarmonicForce {
                    shape,
                    omega,
                    phase,
                } = h;
                HarmonicForceSpec {
                    shape,
                    omega,
                    phase,
                }
            })
            .collect(),
        g_matrix: g_matrix.map(dense).unwrap_or_default(),
        g_offset: some_if_nonempty(g_offset),
        restitution,
        q0: some_if_nonempty(q0),
        v0: some_if_nonempty(v0),
    })
}

fn integrator_spec(p: pb::IntegratorSpec) -> Result<IntegratorSpec, SpecError> {
    use pb::integrator_spec::Scheme;
    let pb::IntegratorSpec { scheme } = p;
    Ok(match scheme {
        None => IntegratorSpec::default(),
        Some(Scheme::MoreauJean(m)) => IntegratorSpec::MoreauJean(moreau_jean(m)?),
        Some(Scheme::MoreauJeanVariant(m)) => IntegratorSpec::MoreauJeanVariant(moreau_jean(m)?),
    })
}

fn moreau_jean(p: pb::MoreauJean) -> Result<MoreauJeanSpec, SpecError> {
    let pb::MoreauJean {
        theta,
        activation,
        activation_gamma,
    } = p;
    let d = MoreauJeanSpec::default();
    let activation = match pb::Activation::try_from(activation) {
        Ok(pb::Activation::Unspecified) => d.activation,
        Ok(pb::Activation::GapAndVelocity) => Activation::GapAndVelocity,
        Ok(pb::Activation::PredictedGap) => Activation::PredictedGap,
        Err(_) => {
            return Err(SpecError::new(
                "integrator.activation",
                format!("unknown value {activation}"),
            ));
        }
    };
    Ok(MoreauJeanSpec {
        theta: theta.unwrap_or(d.theta),
        activation,
        activation_gamma,
    })
}

fn time_spec(p: pb::TimeSpec) -> Result<TimeSpec, SpecError> {
    let pb::TimeSpec {
        h,
        t_end,
        steps,
        pattern,
        adjust,
    } = p;
    Ok(TimeSpec {
        h: h.ok_or_else(|| SpecError::new("time.h", "missing field `h`"))?,
        t_end,
        steps,
        pattern: some_if_nonempty(pattern),
        adjust,
    })
}

fn contact_solver_spec(p: pb::ContactSolverSpec) -> Result<ContactSolverSpec, SpecError> {
    let pb::ContactSolverSpec {
        kind,
        tolerance,
        max_iterations,
    } = p;
    let d = ContactSolverSpec::default();
    let kind = match pb::LcpSolver::try_from(kind) {
        Ok(pb::LcpSolver::Unspecified) => d.kind,
        Ok(pb::LcpSolver::Auto) => LcpSolverKind::Auto,
        Ok(pb::LcpSolver::Lemke) => LcpSolverKind::Lemke,
        Ok(pb::LcpSolver::Pgs) => LcpSolverKind::Pgs,
        Ok(pb::LcpSolver::Enum) => LcpSolverKind::Enumeration,
        Err(_) => {
            return Err(SpecError::new(
                "contact_solver.kind",
                format!("unknown value {kind}"),
            ));
        }
    };
    Ok(ContactSolverSpec {
        kind,
        tolerance: tolerance.unwrap_or(d.tolerance),
        max_iterations: max_iterations
            .map(|m| usize_of("contact_solver.max_iterations", m))
            .transpose()?
            .unwrap_or(d.max_iterations),
    })
}

fn output_spec(p: pb::OutputSpec) -> Result<OutputSpec, SpecError> {
    let pb::OutputSpec { every, probes } = p;
    let d = OutputSpec::default();
    Ok(OutputSpec {
        every: every.unwrap_or(d.every),
        probes: probes
            .into_iter()
            .map(|j| usize_of("output.probes", j))
            .collect::<Result<_, _>>()?,
    })
}

/// A job state → proto.
pub fn state_to_proto(s: JobState) -> pb::JobState {
    match s {
        JobState::Queued => pb::JobState::Queued,
        JobState::Running => pb::JobState::Running,
        JobState::Succeeded => pb::JobState::Succeeded,
        JobState::Failed => pb::JobState::Failed,
        JobState::Cancelled => pb::JobState::Cancelled,
    }
}

/// A proto job state → the service's (None for UNSPECIFIED or unknown values).
pub fn state_from_proto(s: i32) -> Option<JobState> {
    match pb::JobState::try_from(s).ok()? {
        pb::JobState::Unspecified => None,
        pb::JobState::Queued => Some(JobState::Queued),
        pb::JobState::Running => Some(JobState::Running),
        pb::JobState::Succeeded => Some(JobState::Succeeded),
        pb::JobState::Failed => Some(JobState::Failed),
        pb::JobState::Cancelled => Some(JobState::Cancelled),
    }
}

/// A status view → proto (the gRPC `JobStatus` and the zenoh status frame).
pub fn status_to_proto(v: &JobView) -> pb::JobStatus {
    let JobView {
        id,
        name,
        state,
        done,
        total,
        t,
        error,
        created_ms,
        started_ms,
        finished_ms,
    } = v;
    pb::JobStatus {
        id: id.clone(),
        state: state_to_proto(*state) as i32,
        progress: Some(pb::Progress {
            step: *done,
            total: *total,
            t: *t,
            fraction: v.fraction(),
        }),
        name: name.clone(),
        error: error.as_ref().map(|(field, reason)| pb::JobError {
            field: field.clone(),
            reason: reason.clone(),
        }),
        created_ms: *created_ms,
        started_ms: *started_ms,
        finished_ms: *finished_ms,
    }
}

/// A stored result → proto (column-major series).
pub fn result_to_proto(view: &JobView, r: &StoredResult) -> pb::JobResult {
    let StoredResult {
        summary,
        columns,
        steps,
        t,
        values: _,
        tables,
    } = r;
    pb::JobResult {
        id: view.id.clone(),
        status: Some(status_to_proto(view)),
        summary_json: serde_json::Value::Object(summary.clone()).to_string(),
        columns: columns.clone(),
        step: steps.clone(),
        t: t.clone(),
        series: columns
            .iter()
            .enumerate()
            .map(|(c, name)| pb::Series {
                column: name.clone(),
                values: r.column(c),
            })
            .collect(),
        tables: tables
            .iter()
            .map(|tb| pb::Table {
                name: tb.name.clone(),
                columns: tb.columns.clone(),
                rows: tb
                    .rows
                    .iter()
                    .map(|row| pb::Row {
                        values: row.clone(),
                    })
                    .collect(),
            })
            .collect(),
    }
}

/// The capabilities description → proto.
pub fn capabilities_to_proto(
    c: &signorini_core::capabilities::Capabilities,
) -> pb::CapabilitiesResponse {
    use signorini_core::capabilities::{Component, Parameter};
    let comp = |c: &Component| pb::Component {
        name: c.name.to_string(),
        description: c.description.to_string(),
        parameters: c
            .parameters
            .iter()
            .map(|p: &Parameter| pb::Parameter {
                name: p.name.to_string(),
                kind: p.kind.to_string(),
                default_value: p.default.to_string(),
                range: p.range.to_string(),
                description: p.description.to_string(),
            })
            .collect(),
    };
    pb::CapabilitiesResponse {
        models: c.models.iter().map(comp).collect(),
        integrators: c.integrators.iter().map(comp).collect(),
        contact_solvers: c.contact_solvers.iter().map(comp).collect(),
        sections: c.sections.iter().map(comp).collect(),
    }
}
