//! Conversions at the gRPC edge: proto messages ⇄ the core's `JobSpec` (one domain type), and
//! the capabilities → proto. Every proto message and every core spec struct is destructured
//! field by field (no `..`), so a field added to the `.proto` or to the core spec breaks the build
//! here until it is handled. These conversions only move data; validation happens once, in
//! `Job::from_spec` (a missing required field is reported with its path, like serde does for JSON
//! and TOML).
//!
//! The typed message mirrors the whole spec. One thing it cannot say: proto3 `repeated` fields have
//! no presence, so an empty list means "absent" (the default). `job_spec_to_proto` followed by
//! `job_spec` gives back an equal spec whenever no optional list is `Some(vec![])` — which the core
//! rejects anyway for every such list that must be non-empty (tests/service_spec_roundtrip.rs runs
//! this over every file in `examples/`).

use crate::proto::v1 as pb;
use signorini_core::contact::Activation;
use signorini_core::lcp::LcpSolverKind;
use signorini_core::modal::forced::Excitation;
use signorini_core::modal::{AnalysisSpec, ForcedResponseSpec, ModalSpec};
use signorini_core::scenes::{BarSpec, BouncingBall, Chain, HarmonicSpec, LeftEnd, MassMatrix};
use signorini_core::soi2::models::{JayNegrutTest, Pendulum, SliderCrank};
use signorini_core::soi2::run::{HhtSoi2Spec, NewtonSpec, Soi2GeneralizedAlphaSpec, StartSpec};
use signorini_core::spec::{
    ContactSolverSpec, HarmonicForceSpec, IntegratorSpec, JobSpec, LinearSpec, ModelSpec,
    MoreauJeanSpec, NsAlphaSpec, NsHhtSpec, NsNewmarkSpec, OutputSpec, PositionContactSpec,
    SpecError, TimeSpec, WfemSpec,
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
        analysis,
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
        analysis: analysis.map(analysis_spec).transpose()?,
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
            Scene::Pendulum(p) => ModelSpec::Pendulum(pendulum(p)),
            Scene::SliderCrank(s) => ModelSpec::SliderCrank(slider_crank(s)),
            Scene::JayNegrutTest(j) => ModelSpec::JayNegrutTest(jay_negrut_test(j)),
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
        Some(Scheme::NsNewmark(n)) => IntegratorSpec::NsNewmark(ns_newmark(n)?),
        Some(Scheme::NsHht(n)) => IntegratorSpec::NsHht(ns_hht(n)?),
        Some(Scheme::NsGeneralizedAlpha(a)) => IntegratorSpec::NsGeneralizedAlpha(ns_alpha(a)?),
        Some(Scheme::NsKhAlpha(a)) => IntegratorSpec::NsKhAlpha(ns_alpha(a)?),
        Some(Scheme::NewmarkPositionContact(p)) => {
            IntegratorSpec::NewmarkPositionContact(position_contact(p))
        }
        Some(Scheme::HhtPositionContact(p)) => {
            IntegratorSpec::HhtPositionContact(position_contact(p))
        }
        Some(Scheme::Wfem(w)) => {
            let pb::Wfem {} = w;
            IntegratorSpec::Wfem(WfemSpec {})
        }
        Some(Scheme::Soi2GeneralizedAlpha(g)) => {
            IntegratorSpec::Soi2GeneralizedAlpha(soi2_generalized_alpha(g)?)
        }
        Some(Scheme::Soi2Hht(h)) => IntegratorSpec::Soi2Hht(hht_soi2(h)?),
        Some(Scheme::HhtI3(h)) => IntegratorSpec::HhtI3(hht_soi2(h)?),
    })
}

fn activation(p: i32) -> Result<Activation, SpecError> {
    match pb::Activation::try_from(p) {
        Ok(pb::Activation::Unspecified) => Ok(Activation::default()),
        Ok(pb::Activation::GapAndVelocity) => Ok(Activation::GapAndVelocity),
        Ok(pb::Activation::PredictedGap) => Ok(Activation::PredictedGap),
        Err(_) => Err(SpecError::new(
            "integrator.activation",
            format!("unknown value {p}"),
        )),
    }
}

fn ns_newmark(p: pb::NsNewmark) -> Result<NsNewmarkSpec, SpecError> {
    let pb::NsNewmark {
        beta,
        gamma,
        activation: act,
        activation_gamma,
        allow_unstable,
    } = p;
    let d: NsNewmarkSpec = serde_defaults("integrator")?;
    Ok(NsNewmarkSpec {
        beta: beta.unwrap_or(d.beta),
        gamma: gamma.unwrap_or(d.gamma),
        activation: activation(act)?,
        activation_gamma,
        allow_unstable,
    })
}

fn ns_hht(p: pb::NsHht) -> Result<NsHhtSpec, SpecError> {
    let pb::NsHht {
        alpha,
        beta,
        gamma,
        activation: act,
        activation_gamma,
        allow_unstable,
    } = p;
    Ok(NsHhtSpec {
        alpha: alpha.ok_or_else(|| SpecError::new("integrator.alpha", "missing field `alpha`"))?,
        beta,
        gamma,
        activation: activation(act)?,
        activation_gamma,
        allow_unstable,
    })
}

fn ns_alpha(p: pb::NsAlpha) -> Result<NsAlphaSpec, SpecError> {
    let pb::NsAlpha {
        rho_inf,
        alpha_m,
        alpha_f,
        beta,
        gamma,
        activation: act,
        activation_gamma,
        allow_unstable,
    } = p;
    Ok(NsAlphaSpec {
        rho_inf,
        alpha_m,
        alpha_f,
        beta,
        gamma,
        activation: activation(act)?,
        activation_gamma,
        allow_unstable,
    })
}

fn position_contact(p: pb::PositionContact) -> PositionContactSpec {
    let pb::PositionContact {
        alpha,
        beta,
        gamma,
        allow_unstable,
    } = p;
    PositionContactSpec {
        alpha,
        beta,
        gamma,
        allow_unstable,
    }
}

fn soi2_start(p: i32) -> Result<StartSpec, SpecError> {
    match pb::Soi2Start::try_from(p) {
        Ok(pb::Soi2Start::Unspecified) => Ok(StartSpec::default()),
        Ok(pb::Soi2Start::A0) => Ok(StartSpec::A0),
        Ok(pb::Soi2Start::LunkSimeon) => Ok(StartSpec::LunkSimeon),
        Err(_) => Err(SpecError::new(
            "integrator.start",
            format!("unknown value {p}"),
        )),
    }
}

fn soi2_newton(p: i32) -> Result<NewtonSpec, SpecError> {
    match pb::Soi2Newton::try_from(p) {
        Ok(pb::Soi2Newton::Unspecified) => Ok(NewtonSpec::default()),
        Ok(pb::Soi2Newton::Simplified) => Ok(NewtonSpec::Simplified),
        Ok(pb::Soi2Newton::Full) => Ok(NewtonSpec::Full),
        Err(_) => Err(SpecError::new(
            "integrator.newton",
            format!("unknown value {p}"),
        )),
    }
}

fn soi2_generalized_alpha(
    p: pb::Soi2GeneralizedAlpha,
) -> Result<Soi2GeneralizedAlphaSpec, SpecError> {
    let pb::Soi2GeneralizedAlpha {
        rho_inf,
        alpha_m,
        alpha_f,
        beta,
        gamma,
        additive,
        start,
        newton_tolerance,
        newton_max_iterations,
        consistency_tolerance,
        newton,
    } = p;
    let d = Soi2GeneralizedAlphaSpec::default();
    Ok(Soi2GeneralizedAlphaSpec {
        rho_inf,
        alpha_m,
        alpha_f,
        beta,
        gamma,
        additive,
        start: soi2_start(start)?,
        newton_tolerance: newton_tolerance.unwrap_or(d.newton_tolerance),
        newton_max_iterations: newton_max_iterations
            .map(|n| usize_of("integrator.newton_max_iterations", n))
            .transpose()?
            .unwrap_or(d.newton_max_iterations),
        newton: soi2_newton(newton)?,
        consistency_tolerance: consistency_tolerance.unwrap_or(d.consistency_tolerance),
    })
}

fn hht_soi2(p: pb::HhtSoi2) -> Result<HhtSoi2Spec, SpecError> {
    let pb::HhtSoi2 {
        alpha,
        start,
        newton_tolerance,
        newton_max_iterations,
        consistency_tolerance,
        newton,
    } = p;
    let d = HhtSoi2Spec::default();
    Ok(HhtSoi2Spec {
        alpha: alpha.unwrap_or(d.alpha),
        start: soi2_start(start)?,
        newton_tolerance: newton_tolerance.unwrap_or(d.newton_tolerance),
        newton_max_iterations: newton_max_iterations
            .map(|n| usize_of("integrator.newton_max_iterations", n))
            .transpose()?
            .unwrap_or(d.newton_max_iterations),
        newton: soi2_newton(newton)?,
        consistency_tolerance: consistency_tolerance.unwrap_or(d.consistency_tolerance),
    })
}

fn pendulum(p: pb::Pendulum) -> Pendulum {
    let pb::Pendulum {
        mass,
        length,
        stiffness,
        damping,
        gravity,
        theta0,
        omega0,
        y0,
        z0,
    } = p;
    let d = Pendulum::default();
    Pendulum {
        mass: mass.unwrap_or(d.mass),
        length: length.unwrap_or(d.length),
        stiffness: stiffness.unwrap_or(d.stiffness),
        damping: damping.unwrap_or(d.damping),
        gravity: gravity.unwrap_or(d.gravity),
        theta0: theta0.unwrap_or(d.theta0),
        omega0: omega0.unwrap_or(d.omega0),
        y0: some_if_nonempty(y0),
        z0: some_if_nonempty(z0),
    }
}

fn slider_crank(p: pb::SliderCrank) -> SliderCrank {
    let pb::SliderCrank {
        crank_length,
        crank_mass,
        rod_length,
        rod_mass,
        slider_mass,
        gravity,
        crank_angle,
        crank_speed,
    } = p;
    let d = SliderCrank::default();
    SliderCrank {
        crank_length: crank_length.unwrap_or(d.crank_length),
        crank_mass: crank_mass.unwrap_or(d.crank_mass),
        rod_length: rod_length.unwrap_or(d.rod_length),
        rod_mass: rod_mass.unwrap_or(d.rod_mass),
        slider_mass: slider_mass.unwrap_or(d.slider_mass),
        gravity: gravity.unwrap_or(d.gravity),
        crank_angle: crank_angle.unwrap_or(d.crank_angle),
        crank_speed: crank_speed.unwrap_or(d.crank_speed),
    }
}

fn jay_negrut_test(p: pb::JayNegrutTest) -> JayNegrutTest {
    let pb::JayNegrutTest { y0, z0 } = p;
    JayNegrutTest {
        y0: some_if_nonempty(y0),
        z0: some_if_nonempty(z0),
    }
}

fn analysis_spec(p: pb::AnalysisSpec) -> Result<AnalysisSpec, SpecError> {
    use pb::analysis_spec::Kind;
    let pb::AnalysisSpec { kind } = p;
    Ok(
        match kind.ok_or_else(|| SpecError::new("analysis.kind", "missing: choose a kind"))? {
            Kind::NonsmoothModes(m) => AnalysisSpec::NonsmoothModes(nonsmooth_modes(m)?),
            Kind::ForcedResponse(f) => AnalysisSpec::ForcedResponse(forced_response(f)?),
        },
    )
}

/// The serde defaults of a section whose fields all have one (read off an empty object, so the
/// defaults are written once, in the core).
fn serde_defaults<T: serde::de::DeserializeOwned>(section: &str) -> Result<T, SpecError> {
    serde_json::from_value(serde_json::json!({}))
        .map_err(|e| SpecError::new(section, e.to_string()))
}

fn opt_usize(field: &str, v: Option<u64>) -> Result<Option<usize>, SpecError> {
    v.map(|v| usize_of(field, v)).transpose()
}

fn nonsmooth_modes(p: pb::NonsmoothModes) -> Result<ModalSpec, SpecError> {
    let pb::NonsmoothModes {
        cells,
        gap,
        gaps,
        max_period_steps,
        min_period_steps,
        phases,
        length,
        young,
        density,
        area,
        stability_periods,
        all_candidates,
    } = p;
    let d: ModalSpec = serde_defaults("analysis")?;
    Ok(ModalSpec {
        cells: opt_usize("analysis.cells", cells)?.unwrap_or(d.cells),
        gap,
        gaps: some_if_nonempty(gaps),
        max_period_steps: opt_usize("analysis.max_period_steps", max_period_steps)?,
        min_period_steps: opt_usize("analysis.min_period_steps", min_period_steps)?,
        phases: opt_usize("analysis.phases", phases)?.unwrap_or(d.phases),
        length: length.unwrap_or(d.length),
        young: young.unwrap_or(d.young),
        density: density.unwrap_or(d.density),
        area: area.unwrap_or(d.area),
        stability_periods: opt_usize("analysis.stability_periods", stability_periods)?
            .unwrap_or(d.stability_periods),
        all_candidates: all_candidates.unwrap_or(d.all_candidates),
    })
}

fn forced_response(p: pb::ForcedResponse) -> Result<ForcedResponseSpec, SpecError> {
    let pb::ForcedResponse {
        cells,
        length,
        young,
        density,
        area,
        gap,
        excitation,
        amplitude,
        omegas,
        damping,
        transient_periods,
        average_periods,
        backbone,
    } = p;
    let d: ForcedResponseSpec = serde_defaults("analysis")?;
    let excitation = match pb::Excitation::try_from(excitation) {
        Ok(pb::Excitation::Unspecified) => d.excitation,
        Ok(pb::Excitation::Wall) => Excitation::Wall,
        Ok(pb::Excitation::Force) => Excitation::Force,
        Err(_) => {
            return Err(SpecError::new(
                "analysis.excitation",
                format!("unknown value {excitation}"),
            ));
        }
    };
    Ok(ForcedResponseSpec {
        cells: opt_usize("analysis.cells", cells)?.unwrap_or(d.cells),
        length: length.unwrap_or(d.length),
        young: young.unwrap_or(d.young),
        density: density.unwrap_or(d.density),
        area: area.unwrap_or(d.area),
        gap: gap.unwrap_or(d.gap),
        excitation,
        amplitude: amplitude.unwrap_or(d.amplitude),
        omegas: some_if_nonempty(omegas),
        damping: if damping.is_empty() {
            d.damping
        } else {
            damping
        },
        transient_periods: opt_usize("analysis.transient_periods", transient_periods)?
            .unwrap_or(d.transient_periods),
        average_periods: opt_usize("analysis.average_periods", average_periods)?
            .unwrap_or(d.average_periods),
        backbone: backbone.unwrap_or(d.backbone),
    })
}

fn moreau_jean(p: pb::MoreauJean) -> Result<MoreauJeanSpec, SpecError> {
    let pb::MoreauJean {
        theta,
        activation,
        activation_gamma,
    } = p;
    let d = MoreauJeanSpec::default();
    Ok(MoreauJeanSpec {
        theta: theta.unwrap_or(d.theta),
        activation: self::activation(activation)?,
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

/// The core spec → the typed proto message (the inverse of [`job_spec`]: every value is written
/// explicitly, defaults included, so converting back gives an equal spec; see the module note on
/// empty lists).
pub fn job_spec_to_proto(s: &JobSpec) -> pb::JobSpec {
    let JobSpec {
        name,
        model,
        integrator,
        time,
        contact_solver,
        output,
        analysis,
    } = s;
    pb::JobSpec {
        name: name.clone(),
        model: model.as_ref().map(model_to_proto),
        integrator: Some(integrator_to_proto(integrator)),
        time: time.as_ref().map(time_to_proto),
        contact_solver: Some(contact_solver_to_proto(contact_solver)),
        output: Some(output_to_proto(output)),
        analysis: analysis.as_ref().map(analysis_to_proto),
    }
}

fn u64_of(v: usize) -> u64 {
    // usize is at most 64 bits on every target we build for.
    v as u64
}

fn model_to_proto(m: &ModelSpec) -> pb::ModelSpec {
    use pb::model_spec::Scene;
    let scene = match m {
        ModelSpec::BouncingBall(b) => {
            let BouncingBall {
                mass,
                gravity,
                q0,
                v0,
                restitution,
            } = b;
            Scene::BouncingBall(pb::BouncingBall {
                mass: Some(*mass),
                gravity: Some(*gravity),
                q0: Some(*q0),
                v0: Some(*v0),
                restitution: Some(*restitution),
            })
        }
        ModelSpec::Bar(b) => Scene::Bar(bar_to_proto(b)),
        ModelSpec::DepBar(b) => Scene::DepBar(bar_to_proto(b)),
        ModelSpec::Chain(c) => {
            let Chain {
                masses,
                stiffness,
                positions,
                velocities,
                wall,
                restitution,
                force,
            } = c;
            Scene::Chain(pb::ChainModel {
                masses: masses.clone(),
                stiffness: Some(*stiffness),
                positions: positions.clone(),
                velocities: velocities.clone(),
                wall: Some(*wall),
                restitution: Some(*restitution),
                force: force.clone().unwrap_or_default(),
            })
        }
        ModelSpec::Linear(l) => Scene::Linear(linear_to_proto(l)),
        ModelSpec::Pendulum(p) => {
            let Pendulum {
                mass,
                length,
                stiffness,
                damping,
                gravity,
                theta0,
                omega0,
                y0,
                z0,
            } = p;
            Scene::Pendulum(pb::Pendulum {
                mass: Some(*mass),
                length: Some(*length),
                stiffness: Some(*stiffness),
                damping: Some(*damping),
                gravity: Some(*gravity),
                theta0: Some(*theta0),
                omega0: Some(*omega0),
                y0: y0.clone().unwrap_or_default(),
                z0: z0.clone().unwrap_or_default(),
            })
        }
        ModelSpec::SliderCrank(c) => {
            let SliderCrank {
                crank_length,
                crank_mass,
                rod_length,
                rod_mass,
                slider_mass,
                gravity,
                crank_angle,
                crank_speed,
            } = c;
            Scene::SliderCrank(pb::SliderCrank {
                crank_length: Some(*crank_length),
                crank_mass: Some(*crank_mass),
                rod_length: Some(*rod_length),
                rod_mass: Some(*rod_mass),
                slider_mass: Some(*slider_mass),
                gravity: Some(*gravity),
                crank_angle: Some(*crank_angle),
                crank_speed: Some(*crank_speed),
            })
        }
        ModelSpec::JayNegrutTest(j) => {
            let JayNegrutTest { y0, z0 } = j;
            Scene::JayNegrutTest(pb::JayNegrutTest {
                y0: y0.clone().unwrap_or_default(),
                z0: z0.clone().unwrap_or_default(),
            })
        }
    };
    pb::ModelSpec { scene: Some(scene) }
}

fn harmonic_to_proto(h: &HarmonicSpec) -> pb::Harmonic {
    let HarmonicSpec { amplitude, omega } = h;
    pb::Harmonic {
        amplitude: *amplitude,
        omega: *omega,
    }
}

fn bar_to_proto(b: &BarSpec) -> pb::BarModel {
    let BarSpec {
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
    } = b;
    pb::BarModel {
        elements: elements.map(u64_of),
        length: *length,
        young: *young,
        density: *density,
        area: *area,
        mass_matrix: match mass_matrix {
            None => pb::MassMatrix::Unspecified,
            Some(MassMatrix::Lumped) => pb::MassMatrix::Lumped,
            Some(MassMatrix::Consistent) => pb::MassMatrix::Consistent,
        } as i32,
        left: match left {
            None => pb::LeftEnd::Unspecified,
            Some(LeftEnd::Fixed) => pb::LeftEnd::Fixed,
            Some(LeftEnd::Free) => pb::LeftEnd::Free,
        } as i32,
        gap: *gap,
        restitution: *restitution,
        initial_velocity: *initial_velocity,
        initial_displacement: *initial_displacement,
        body_force: *body_force,
        rayleigh_mass: *rayleigh_mass,
        rayleigh_stiffness: *rayleigh_stiffness,
        harmonic_force: harmonic_force.as_ref().map(harmonic_to_proto),
        wall_motion: wall_motion.as_ref().map(harmonic_to_proto),
    }
}

fn dense_to_proto(m: &[Vec<f64>]) -> pb::DenseMatrix {
    pb::DenseMatrix {
        rows: m.iter().map(|r| pb::Row { values: r.clone() }).collect(),
    }
}

fn triplets_to_proto(t: &Option<Triplets>) -> Vec<pb::Triplet> {
    t.iter()
        .flatten()
        .map(|&(row, col, value)| pb::Triplet {
            row: u64_of(row),
            col: u64_of(col),
            value,
        })
        .collect()
}

fn linear_to_proto(l: &LinearSpec) -> pb::LinearModel {
    let LinearSpec {
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
    } = l;
    pb::LinearModel {
        mass: mass.as_deref().map(dense_to_proto),
        mass_triplets: triplets_to_proto(mass_triplets),
        stiffness: stiffness.as_deref().map(dense_to_proto),
        stiffness_triplets: triplets_to_proto(stiffness_triplets),
        damping: damping.as_deref().map(dense_to_proto),
        damping_triplets: triplets_to_proto(damping_triplets),
        force: force.clone().unwrap_or_default(),
        harmonic_force: harmonic_force
            .iter()
            .map(|h| {
                let HarmonicForceSpec {
                    shape,
                    omega,
                    phase,
                } = h;
                pb::HarmonicForce {
                    shape: shape.clone(),
                    omega: *omega,
                    phase: *phase,
                }
            })
            .collect(),
        g_matrix: Some(dense_to_proto(g_matrix)),
        g_offset: g_offset.clone().unwrap_or_default(),
        restitution: restitution.clone(),
        q0: q0.clone().unwrap_or_default(),
        v0: v0.clone().unwrap_or_default(),
    }
}

fn activation_to_proto(a: Activation) -> i32 {
    let a = match a {
        Activation::GapAndVelocity => pb::Activation::GapAndVelocity,
        Activation::PredictedGap => pb::Activation::PredictedGap,
    };
    a as i32
}

fn start_to_proto(s: StartSpec) -> i32 {
    let s = match s {
        StartSpec::A0 => pb::Soi2Start::A0,
        StartSpec::LunkSimeon => pb::Soi2Start::LunkSimeon,
    };
    s as i32
}

fn newton_to_proto(n: NewtonSpec) -> i32 {
    let n = match n {
        NewtonSpec::Simplified => pb::Soi2Newton::Simplified,
        NewtonSpec::Full => pb::Soi2Newton::Full,
    };
    n as i32
}

fn integrator_to_proto(i: &IntegratorSpec) -> pb::IntegratorSpec {
    use pb::integrator_spec::Scheme;
    let mj = |m: &MoreauJeanSpec| {
        let MoreauJeanSpec {
            theta,
            activation,
            activation_gamma,
        } = m;
        pb::MoreauJean {
            theta: Some(*theta),
            activation: activation_to_proto(*activation),
            activation_gamma: *activation_gamma,
        }
    };
    let alpha = |a: &NsAlphaSpec| {
        let NsAlphaSpec {
            rho_inf,
            alpha_m,
            alpha_f,
            beta,
            gamma,
            activation,
            activation_gamma,
            allow_unstable,
        } = a;
        pb::NsAlpha {
            rho_inf: *rho_inf,
            alpha_m: *alpha_m,
            alpha_f: *alpha_f,
            beta: *beta,
            gamma: *gamma,
            activation: activation_to_proto(*activation),
            activation_gamma: *activation_gamma,
            allow_unstable: *allow_unstable,
        }
    };
    let pc = |p: &PositionContactSpec| {
        let PositionContactSpec {
            alpha,
            beta,
            gamma,
            allow_unstable,
        } = p;
        pb::PositionContact {
            alpha: *alpha,
            beta: *beta,
            gamma: *gamma,
            allow_unstable: *allow_unstable,
        }
    };
    let hht_soi2 = |h: &HhtSoi2Spec| {
        let HhtSoi2Spec {
            alpha,
            start,
            newton_tolerance,
            newton_max_iterations,
            newton,
            consistency_tolerance,
        } = h;
        pb::HhtSoi2 {
            alpha: Some(*alpha),
            start: start_to_proto(*start),
            newton_tolerance: Some(*newton_tolerance),
            newton_max_iterations: Some(u64_of(*newton_max_iterations)),
            consistency_tolerance: Some(*consistency_tolerance),
            newton: newton_to_proto(*newton),
        }
    };
    let scheme = match i {
        IntegratorSpec::MoreauJean(m) => Scheme::MoreauJean(mj(m)),
        IntegratorSpec::MoreauJeanVariant(m) => Scheme::MoreauJeanVariant(mj(m)),
        IntegratorSpec::NsNewmark(n) => {
            let NsNewmarkSpec {
                beta,
                gamma,
                activation,
                activation_gamma,
                allow_unstable,
            } = n;
            Scheme::NsNewmark(pb::NsNewmark {
                beta: Some(*beta),
                gamma: Some(*gamma),
                activation: activation_to_proto(*activation),
                activation_gamma: *activation_gamma,
                allow_unstable: *allow_unstable,
            })
        }
        IntegratorSpec::NsHht(n) => {
            let NsHhtSpec {
                alpha,
                beta,
                gamma,
                activation,
                activation_gamma,
                allow_unstable,
            } = n;
            Scheme::NsHht(pb::NsHht {
                alpha: Some(*alpha),
                beta: *beta,
                gamma: *gamma,
                activation: activation_to_proto(*activation),
                activation_gamma: *activation_gamma,
                allow_unstable: *allow_unstable,
            })
        }
        IntegratorSpec::NsGeneralizedAlpha(a) => Scheme::NsGeneralizedAlpha(alpha(a)),
        IntegratorSpec::NsKhAlpha(a) => Scheme::NsKhAlpha(alpha(a)),
        IntegratorSpec::NewmarkPositionContact(p) => Scheme::NewmarkPositionContact(pc(p)),
        IntegratorSpec::HhtPositionContact(p) => Scheme::HhtPositionContact(pc(p)),
        IntegratorSpec::Soi2GeneralizedAlpha(g) => {
            let Soi2GeneralizedAlphaSpec {
                rho_inf,
                alpha_m,
                alpha_f,
                beta,
                gamma,
                additive,
                start,
                newton_tolerance,
                newton_max_iterations,
                newton,
                consistency_tolerance,
            } = g;
            Scheme::Soi2GeneralizedAlpha(pb::Soi2GeneralizedAlpha {
                rho_inf: *rho_inf,
                alpha_m: *alpha_m,
                alpha_f: *alpha_f,
                beta: *beta,
                gamma: *gamma,
                additive: *additive,
                start: start_to_proto(*start),
                newton_tolerance: Some(*newton_tolerance),
                newton_max_iterations: Some(u64_of(*newton_max_iterations)),
                consistency_tolerance: Some(*consistency_tolerance),
                newton: newton_to_proto(*newton),
            })
        }
        IntegratorSpec::Soi2Hht(h) => Scheme::Soi2Hht(hht_soi2(h)),
        IntegratorSpec::HhtI3(h) => Scheme::HhtI3(hht_soi2(h)),
        IntegratorSpec::Wfem(w) => {
            let WfemSpec {} = w;
            Scheme::Wfem(pb::Wfem {})
        }
    };
    pb::IntegratorSpec {
        scheme: Some(scheme),
    }
}

fn time_to_proto(t: &TimeSpec) -> pb::TimeSpec {
    let TimeSpec {
        h,
        t_end,
        steps,
        pattern,
        adjust,
    } = t;
    pb::TimeSpec {
        h: Some(*h),
        t_end: *t_end,
        steps: *steps,
        pattern: pattern.clone().unwrap_or_default(),
        adjust: *adjust,
    }
}

fn contact_solver_to_proto(c: &ContactSolverSpec) -> pb::ContactSolverSpec {
    let ContactSolverSpec {
        kind,
        tolerance,
        max_iterations,
    } = c;
    pb::ContactSolverSpec {
        kind: match kind {
            LcpSolverKind::Auto => pb::LcpSolver::Auto,
            LcpSolverKind::Lemke => pb::LcpSolver::Lemke,
            LcpSolverKind::Pgs => pb::LcpSolver::Pgs,
            LcpSolverKind::Enumeration => pb::LcpSolver::Enum,
        } as i32,
        tolerance: Some(*tolerance),
        max_iterations: Some(u64_of(*max_iterations)),
    }
}

fn output_to_proto(o: &OutputSpec) -> pb::OutputSpec {
    let OutputSpec { every, probes } = o;
    pb::OutputSpec {
        every: Some(*every),
        probes: probes.iter().copied().map(u64_of).collect(),
    }
}

fn analysis_to_proto(a: &AnalysisSpec) -> pb::AnalysisSpec {
    use pb::analysis_spec::Kind;
    let kind = match a {
        AnalysisSpec::NonsmoothModes(m) => {
            let ModalSpec {
                cells,
                gap,
                gaps,
                max_period_steps,
                min_period_steps,
                phases,
                length,
                young,
                density,
                area,
                stability_periods,
                all_candidates,
            } = m;
            Kind::NonsmoothModes(pb::NonsmoothModes {
                cells: Some(u64_of(*cells)),
                gap: *gap,
                gaps: gaps.clone().unwrap_or_default(),
                max_period_steps: max_period_steps.map(u64_of),
                min_period_steps: min_period_steps.map(u64_of),
                phases: Some(u64_of(*phases)),
                length: Some(*length),
                young: Some(*young),
                density: Some(*density),
                area: Some(*area),
                stability_periods: Some(u64_of(*stability_periods)),
                all_candidates: Some(*all_candidates),
            })
        }
        AnalysisSpec::ForcedResponse(f) => {
            let ForcedResponseSpec {
                cells,
                length,
                young,
                density,
                area,
                gap,
                excitation,
                amplitude,
                omegas,
                damping,
                transient_periods,
                average_periods,
                backbone,
            } = f;
            Kind::ForcedResponse(pb::ForcedResponse {
                cells: Some(u64_of(*cells)),
                length: Some(*length),
                young: Some(*young),
                density: Some(*density),
                area: Some(*area),
                gap: Some(*gap),
                excitation: match excitation {
                    Excitation::Wall => pb::Excitation::Wall,
                    Excitation::Force => pb::Excitation::Force,
                } as i32,
                amplitude: Some(*amplitude),
                omegas: omegas.clone().unwrap_or_default(),
                damping: damping.clone(),
                transient_periods: Some(u64_of(*transient_periods)),
                average_periods: Some(u64_of(*average_periods)),
                backbone: Some(*backbone),
            })
        }
    };
    pb::AnalysisSpec { kind: Some(kind) }
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
