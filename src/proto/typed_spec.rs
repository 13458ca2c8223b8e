//! The core spec → the typed proto message, the inverse of [`crate::server::convert::job_spec`]
//! (which the service uses): `signorini submit` sends specs typed, and the tests round-trip specs
//! through the wire with it. Every value is written explicitly, defaults included, so converting
//! back gives an equal spec whenever no optional list is `Some(vec![])` (proto3 `repeated`
//! fields have no presence). Every core struct is destructured field by field, so a field added
//! to the core spec breaks this build until it is handled.
//!
//! The sections added after the typed message was frozen — `lagrangian` models, Coulomb friction
//! on `linear` models, `[check]`, `[study]`, the `string` scene, the `obstacle` of a `bar`, the
//! `banded_active_set` contact solver — travel in the JSON spelling of `SubmitJobRequest`
//! only: for a spec that has one, [`job_spec_to_proto`] says which ([`JsonOnly`]).

use crate::proto::v1 as pb;
use signorini_core::contact::Activation;
use signorini_core::lcp::LcpSolverKind;
use signorini_core::scenes::{BarSpec, BouncingBall, Chain, HarmonicSpec, LeftEnd, MassMatrix};
use signorini_core::soi2::models::{JayNegrutTest, Pendulum, SliderCrank};
use signorini_core::spec::{
    AlphaCoefficientsSpec, AnalysisSpec, ContactSolverSpec, Excitation, ForcedResponseSpec,
    HarmonicForceSpec, HhtSoi2Spec, IndexSetSpec, IntegratorSpec, JobSpec, LinearSpec, ModalSpec,
    ModelSpec, MoreauJeanSpec, NewtonSpec, NsAlphaSpec, NsHhtSpec, NsNewmarkSpec, OutputSpec,
    PositionContactSpec, Soi2GeneralizedAlphaSpec, Soi2NewtonSpec, StartSpec, TimeSpec, WfemSpec,
};

type Triplets = Vec<(usize, usize, f64)>;

/// A spec the typed message cannot carry: the section that travels as JSON only.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("{0} has no typed proto message: it travels as the JSON spelling")]
pub struct JsonOnly(pub &'static str);

/// The core spec → the typed proto message, or the section that only the JSON spelling carries.
pub fn job_spec_to_proto(s: &JobSpec) -> Result<pb::JobSpec, JsonOnly> {
    let JobSpec {
        // An editor hint of spec files, not carried by the typed spec.
        schema: _,
        name,
        model,
        integrator,
        time,
        contact_solver,
        output,
        analysis,
        check,
        study,
    } = s;
    if check.is_some() {
        return Err(JsonOnly("[check]"));
    }
    if study.is_some() {
        return Err(JsonOnly("[study]"));
    }
    Ok(pb::JobSpec {
        name: name.clone(),
        model: model.as_ref().map(model_to_proto).transpose()?,
        integrator: Some(integrator_to_proto(integrator)),
        time: time.as_ref().map(time_to_proto),
        contact_solver: Some(contact_solver_to_proto(contact_solver)?),
        output: Some(output_to_proto(output)?),
        analysis: analysis.as_ref().map(analysis_to_proto),
    })
}

fn u64_of(v: usize) -> u64 {
    // usize is at most 64 bits on every target we build for.
    v as u64
}

fn model_to_proto(m: &ModelSpec) -> Result<pb::ModelSpec, JsonOnly> {
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
        ModelSpec::Bar(b) | ModelSpec::DepBar(b) if b.obstacle.is_some() => {
            return Err(JsonOnly("the `obstacle` of a bar"));
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
        ModelSpec::Linear(l) => Scene::Linear(linear_to_proto(l)?),
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
        ModelSpec::Lagrangian(_) => return Err(JsonOnly("scene `lagrangian`")),
        ModelSpec::RigidBodies(_) => return Err(JsonOnly("scene `rigid_bodies`")),
        ModelSpec::String(_) => return Err(JsonOnly("scene `string`")),
    };
    Ok(pb::ModelSpec { scene: Some(scene) })
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
        // Carried by the JSON spelling only (`model_to_proto`).
        obstacle: _,
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

fn linear_to_proto(l: &LinearSpec) -> Result<pb::LinearModel, JsonOnly> {
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
        t_matrix,
        friction,
    } = l;
    if t_matrix.is_some() || friction.is_some() {
        return Err(JsonOnly("Coulomb friction (`t_matrix`, `friction`)"));
    }
    Ok(pb::LinearModel {
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
    })
}

fn activation_to_proto(a: Option<Activation>) -> i32 {
    let a = match a {
        None => pb::Activation::Unspecified,
        Some(Activation::GapAndVelocity) => pb::Activation::GapAndVelocity,
        Some(Activation::PredictedGap) => pb::Activation::PredictedGap,
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

/// The SOI2 Newton group as the proto's (newton_tolerance, newton_max_iterations,
/// consistency_tolerance, newton).
fn solve_to_proto(s: &Soi2NewtonSpec) -> (Option<f64>, Option<u64>, Option<f64>, i32) {
    let Soi2NewtonSpec {
        newton,
        newton_tolerance,
        newton_max_iterations,
        consistency_tolerance,
    } = s;
    (
        Some(*newton_tolerance),
        Some(u64_of(*newton_max_iterations)),
        Some(*consistency_tolerance),
        newton_to_proto(*newton),
    )
}

fn integrator_to_proto(i: &IntegratorSpec) -> pb::IntegratorSpec {
    use pb::integrator_spec::Scheme;
    let scheme = match i {
        IntegratorSpec::MoreauJean(m) => Scheme::MoreauJean(moreau_jean_to_proto(m)),
        IntegratorSpec::MoreauJeanVariant(m) => Scheme::MoreauJeanVariant(moreau_jean_to_proto(m)),
        IntegratorSpec::NsNewmark(n) => Scheme::NsNewmark(ns_newmark_to_proto(n)),
        IntegratorSpec::NsHht(n) => Scheme::NsHht(ns_hht_to_proto(n)),
        IntegratorSpec::NsGeneralizedAlpha(a) => Scheme::NsGeneralizedAlpha(ns_alpha_to_proto(a)),
        IntegratorSpec::NsKhAlpha(a) => Scheme::NsKhAlpha(ns_alpha_to_proto(a)),
        IntegratorSpec::NewmarkPositionContact(p) => {
            Scheme::NewmarkPositionContact(position_contact_to_proto(p))
        }
        IntegratorSpec::HhtPositionContact(p) => {
            Scheme::HhtPositionContact(position_contact_to_proto(p))
        }
        IntegratorSpec::Soi2GeneralizedAlpha(g) => {
            Scheme::Soi2GeneralizedAlpha(soi2_alpha_to_proto(g))
        }
        IntegratorSpec::Soi2Hht(h) => Scheme::Soi2Hht(hht_soi2_to_proto(h)),
        IntegratorSpec::HhtI3(h) => Scheme::HhtI3(hht_soi2_to_proto(h)),
        IntegratorSpec::Wfem(w) => {
            let WfemSpec {} = w;
            Scheme::Wfem(pb::Wfem {})
        }
    };
    pb::IntegratorSpec {
        scheme: Some(scheme),
    }
}

fn moreau_jean_to_proto(m: &MoreauJeanSpec) -> pb::MoreauJean {
    let MoreauJeanSpec { theta, index_set } = m;
    let IndexSetSpec {
        activation,
        activation_gamma,
    } = index_set;
    pb::MoreauJean {
        theta: Some(*theta),
        activation: activation_to_proto(*activation),
        activation_gamma: *activation_gamma,
    }
}

fn ns_newmark_to_proto(n: &NsNewmarkSpec) -> pb::NsNewmark {
    let NsNewmarkSpec {
        beta,
        gamma,
        index_set: IndexSetSpec {
            activation,
            activation_gamma,
        },
        allow_unstable,
    } = n;
    pb::NsNewmark {
        beta: Some(*beta),
        gamma: Some(*gamma),
        activation: activation_to_proto(*activation),
        activation_gamma: *activation_gamma,
        allow_unstable: *allow_unstable,
    }
}

fn ns_hht_to_proto(n: &NsHhtSpec) -> pb::NsHht {
    let NsHhtSpec {
        alpha,
        beta,
        gamma,
        index_set: IndexSetSpec {
            activation,
            activation_gamma,
        },
        allow_unstable,
    } = n;
    pb::NsHht {
        alpha: Some(*alpha),
        beta: *beta,
        gamma: *gamma,
        activation: activation_to_proto(*activation),
        activation_gamma: *activation_gamma,
        allow_unstable: *allow_unstable,
    }
}

fn ns_alpha_to_proto(a: &NsAlphaSpec) -> pb::NsAlpha {
    let NsAlphaSpec {
        coefficients:
            AlphaCoefficientsSpec {
                rho_inf,
                alpha_m,
                alpha_f,
                beta,
                gamma,
            },
        index_set: IndexSetSpec {
            activation,
            activation_gamma,
        },
        allow_unstable,
        newton,
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
        newton: newton.map_or(pb::Soi2Newton::Unspecified as i32, newton_to_proto),
    }
}

fn position_contact_to_proto(p: &PositionContactSpec) -> pb::PositionContact {
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
}

fn soi2_alpha_to_proto(g: &Soi2GeneralizedAlphaSpec) -> pb::Soi2GeneralizedAlpha {
    let Soi2GeneralizedAlphaSpec {
        coefficients:
            AlphaCoefficientsSpec {
                rho_inf,
                alpha_m,
                alpha_f,
                beta,
                gamma,
            },
        additive,
        start,
        solve,
    } = g;
    let (newton_tolerance, newton_max_iterations, consistency_tolerance, newton) =
        solve_to_proto(solve);
    pb::Soi2GeneralizedAlpha {
        rho_inf: *rho_inf,
        alpha_m: *alpha_m,
        alpha_f: *alpha_f,
        beta: *beta,
        gamma: *gamma,
        additive: *additive,
        start: start_to_proto(*start),
        newton_tolerance,
        newton_max_iterations,
        consistency_tolerance,
        newton,
    }
}

fn hht_soi2_to_proto(h: &HhtSoi2Spec) -> pb::HhtSoi2 {
    let HhtSoi2Spec {
        alpha,
        start,
        solve,
    } = h;
    let (newton_tolerance, newton_max_iterations, consistency_tolerance, newton) =
        solve_to_proto(solve);
    pb::HhtSoi2 {
        alpha: Some(*alpha),
        start: start_to_proto(*start),
        newton_tolerance,
        newton_max_iterations,
        consistency_tolerance,
        newton,
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

fn contact_solver_to_proto(c: &ContactSolverSpec) -> Result<pb::ContactSolverSpec, JsonOnly> {
    let ContactSolverSpec {
        kind,
        tolerance,
        max_iterations,
        accept_error,
    } = c;
    Ok(pb::ContactSolverSpec {
        kind: match kind {
            LcpSolverKind::Auto => pb::LcpSolver::Auto,
            LcpSolverKind::Lemke => pb::LcpSolver::Lemke,
            LcpSolverKind::Pgs => pb::LcpSolver::Pgs,
            LcpSolverKind::Enumeration => pb::LcpSolver::Enum,
            LcpSolverKind::BandedActiveSet => {
                return Err(JsonOnly("contact_solver.kind = \"banded_active_set\""));
            }
        } as i32,
        tolerance: Some(*tolerance),
        max_iterations: Some(u64_of(*max_iterations)),
        accept_error: *accept_error,
    })
}

fn output_to_proto(o: &OutputSpec) -> Result<pb::OutputSpec, JsonOnly> {
    let OutputSpec {
        every,
        probes,
        checkpoint_seconds,
        checkpoint_steps,
        contacts,
        vtk,
    } = o;
    if *contacts {
        return Err(JsonOnly("`output.contacts`"));
    }
    if *vtk {
        return Err(JsonOnly("`output.vtk`"));
    }
    Ok(pb::OutputSpec {
        every: Some(*every),
        probes: probes.iter().copied().map(u64_of).collect(),
        checkpoint_seconds: *checkpoint_seconds,
        checkpoint_steps: *checkpoint_steps,
    })
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
