//! Conversions at the gRPC edge: proto messages ⇄ the core's `JobSpec` (one domain type), and
//! the capabilities → proto. Every proto message and every core spec struct is destructured
//! field by field (no `..`), so a field added to the `.proto` or to the core spec breaks the build
//! here until it is handled. These conversions only move data; validation happens once, in
//! `Job::from_spec` (a missing required field is reported with its path, like serde does for JSON
//! and TOML).
//!
//! The typed message mirrors the whole spec. One thing it cannot say: proto3 `repeated` fields have
//! no presence, so an empty list means "absent" (the default). The inverse conversion lives with
//! the tests (`tests/common/to_proto.rs`), which round-trip every file in `examples/` and random
//! specs through the wire (`tests/service_spec_roundtrip.rs`).

use crate::proto::v1 as pb;
use signorini_core::contact::Activation;
use signorini_core::lcp::LcpSolverKind;
use signorini_core::scenes::{BarSpec, BouncingBall, Chain, HarmonicSpec, LeftEnd, MassMatrix};
use signorini_core::soi2::models::{JayNegrutTest, Pendulum, SliderCrank};
use signorini_core::spec::{
    AlphaCoefficientsSpec, AnalysisSpec, ContactSolverSpec, Excitation, ForcedResponseSpec,
    HarmonicForceSpec, HhtSoi2Spec, IndexSetSpec, IntegratorSpec, JobSpec, LinearSpec, ModalSpec,
    ModelSpec, MoreauJeanSpec, NewtonSpec, NsAlphaSpec, NsHhtSpec, NsNewmarkSpec, OutputSpec,
    PositionContactSpec, Soi2GeneralizedAlphaSpec, Soi2NewtonSpec, SpecError, StartSpec, TimeSpec,
    WfemSpec,
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
        // An editor hint of spec files; a typed spec has no file.
        schema: None,
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
        // Read by `signorini check` only: the service ignores it, the typed spec has none.
        check: None,
        // Studies travel as the JSON spelling only.
        study: None,
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
        // The distributed obstacle travels in the JSON spelling only.
        obstacle: None,
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
        // Coulomb friction travels in the JSON spelling only (round-2 sections).
        t_matrix: None,
        friction: None,
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

fn activation(p: i32) -> Result<Option<Activation>, SpecError> {
    match pb::Activation::try_from(p) {
        Ok(pb::Activation::Unspecified) => Ok(None),
        Ok(pb::Activation::GapAndVelocity) => Ok(Some(Activation::GapAndVelocity)),
        Ok(pb::Activation::PredictedGap) => Ok(Some(Activation::PredictedGap)),
        Err(_) => Err(SpecError::new(
            "integrator.activation",
            format!("unknown value {p}"),
        )),
    }
}

fn index_set(act: i32, activation_gamma: Option<f64>) -> Result<IndexSetSpec, SpecError> {
    Ok(IndexSetSpec {
        activation: activation(act)?,
        activation_gamma,
    })
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
        index_set: index_set(act, activation_gamma)?,
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
        index_set: index_set(act, activation_gamma)?,
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
        newton,
    } = p;
    Ok(NsAlphaSpec {
        coefficients: AlphaCoefficientsSpec {
            rho_inf,
            alpha_m,
            alpha_f,
            beta,
            gamma,
        },
        index_set: index_set(act, activation_gamma)?,
        allow_unstable,
        // Unspecified: the scheme's own default (full Newton), not the SOI2 schemes'.
        newton: (newton != pb::Soi2Newton::Unspecified as i32)
            .then(|| soi2_newton(newton))
            .transpose()?,
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

/// The Newton group of the SOI2 schemes; unset fields take the core defaults.
fn soi2_solve(
    newton: i32,
    newton_tolerance: Option<f64>,
    newton_max_iterations: Option<u64>,
    consistency_tolerance: Option<f64>,
) -> Result<Soi2NewtonSpec, SpecError> {
    let d = Soi2NewtonSpec::default();
    Ok(Soi2NewtonSpec {
        newton: soi2_newton(newton)?,
        newton_tolerance: newton_tolerance.unwrap_or(d.newton_tolerance),
        newton_max_iterations: newton_max_iterations
            .map(|n| usize_of("integrator.newton_max_iterations", n))
            .transpose()?
            .unwrap_or(d.newton_max_iterations),
        consistency_tolerance: consistency_tolerance.unwrap_or(d.consistency_tolerance),
    })
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
    Ok(Soi2GeneralizedAlphaSpec {
        coefficients: AlphaCoefficientsSpec {
            rho_inf,
            alpha_m,
            alpha_f,
            beta,
            gamma,
        },
        additive,
        start: soi2_start(start)?,
        solve: soi2_solve(
            newton,
            newton_tolerance,
            newton_max_iterations,
            consistency_tolerance,
        )?,
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
        solve: soi2_solve(
            newton,
            newton_tolerance,
            newton_max_iterations,
            consistency_tolerance,
        )?,
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
        index_set: index_set(activation, activation_gamma)?,
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
        accept_error,
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
        accept_error,
    })
}

fn output_spec(p: pb::OutputSpec) -> Result<OutputSpec, SpecError> {
    let pb::OutputSpec {
        every,
        probes,
        checkpoint_seconds,
        checkpoint_steps,
    } = p;
    let d = OutputSpec::default();
    Ok(OutputSpec {
        every: every.unwrap_or(d.every),
        probes: probes
            .into_iter()
            .map(|j| usize_of("output.probes", j))
            .collect::<Result<_, _>>()?,
        checkpoint_seconds,
        checkpoint_steps,
        contacts: d.contacts,
        vtk: d.vtk,
    })
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
    let signorini_core::capabilities::Capabilities {
        models,
        integrators,
        analyses,
        contact_solvers,
        sections,
        support,
    } = c;
    pb::CapabilitiesResponse {
        models: models.iter().map(comp).collect(),
        integrators: integrators.iter().map(comp).collect(),
        contact_solvers: contact_solvers.iter().map(comp).collect(),
        sections: sections.iter().map(comp).collect(),
        analyses: analyses.iter().map(comp).collect(),
        support: support.iter().map(scheme_support_to_proto).collect(),
    }
}

/// One row of the scheme × feature table → proto.
fn scheme_support_to_proto(
    row: &signorini_core::spec::support::SchemeSupport,
) -> pb::SchemeSupport {
    pb::SchemeSupport {
        scheme: row.scheme.to_string(),
        model: row.family.name().to_string(),
        features: row
            .features
            .iter()
            .map(|(feature, support)| {
                let (kind, field, reason) = support.parts();
                pb::FeatureSupport {
                    feature: feature.name().to_string(),
                    support: kind.to_string(),
                    field: field.to_string(),
                    reason: reason.to_string(),
                }
            })
            .collect(),
    }
}
