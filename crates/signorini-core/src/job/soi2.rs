//! A SOI2 job (`soi2_generalized_alpha`, `soi2_hht`, `hht_i3` on a constrained scene) validated
//! into a [`Soi2Job`]: the scene's parameters, the method's coefficients (Jay & Negrut,
//! Theorem 1), Newton's settings and the consistency of the initial values, each error naming
//! its field. The SOI2 numerics take only the validated job.

use crate::integrators::OutputOptions;
use crate::lagrangian::UserModel;
use crate::soi2::method::{
    Coefficients, Formulation, Method, NewtonOptions, NewtonStrategy, StartValue,
};
use crate::soi2::models::{JayNegrutTest, Pendulum, SliderCrank};
use crate::soi2::run::{Schedule, Soi2Job, Soi2Model, Soi2Output};
use crate::soi2::{ConstrainedModel, Soi2Error, check_consistency, check_constraint_rank};
use crate::spec::support::{self, Feature, ModelFamily};
use crate::spec::{
    IntegratorSpec, JobSpec, ModelSpec, NewtonSpec, Probes, Soi2GeneralizedAlphaSpec,
    Soi2NewtonSpec, SpecError, StartSpec, mismatch,
};

impl From<StartSpec> for StartValue {
    fn from(s: StartSpec) -> Self {
        match s {
            StartSpec::A0 => StartValue::A0,
            StartSpec::LunkSimeon => StartValue::LunkSimeon,
        }
    }
}

impl From<NewtonSpec> for NewtonStrategy {
    fn from(s: NewtonSpec) -> Self {
        match s {
            NewtonSpec::Simplified => NewtonStrategy::Simplified,
            NewtonSpec::Full => NewtonStrategy::Full,
        }
    }
}

/// The validated Newton group: (options, strategy, consistency tolerance); errors name the field.
fn newton_settings(n: &Soi2NewtonSpec) -> Result<(NewtonOptions, NewtonStrategy, f64), SpecError> {
    let finite_positive = |field: &str, x: f64| {
        if x.is_finite() && x > 0.0 {
            Ok(())
        } else {
            Err(SpecError::new(
                format!("integrator.{field}"),
                format!("must be a finite number > 0, got {x}"),
            ))
        }
    };
    finite_positive("consistency_tolerance", n.consistency_tolerance)?;
    finite_positive("newton_tolerance", n.newton_tolerance)?;
    if n.newton_max_iterations == 0 {
        return Err(SpecError::new(
            "integrator.newton_max_iterations",
            "must be ≥ 1",
        ));
    }
    let options = NewtonOptions {
        tolerance: n.newton_tolerance,
        max_iterations: n.newton_max_iterations,
    };
    Ok((options, n.newton.into(), n.consistency_tolerance))
}

/// Checks generalized-α coefficients against Theorem 1's hypotheses; errors name the field.
fn check_coefficients(c: &Coefficients) -> Result<(), SpecError> {
    let f = |name: &str, v: f64| -> Result<(), SpecError> {
        if v.is_finite() {
            Ok(())
        } else {
            Err(SpecError::new(
                format!("integrator.{name}"),
                format!("must be finite, got {v}"),
            ))
        }
    };
    f("alpha_m", c.alpha_m)?;
    f("alpha_f", c.alpha_f)?;
    f("beta", c.beta)?;
    f("gamma", c.gamma)?;
    if c.alpha_m == 1.0 {
        return Err(SpecError::new(
            "integrator.alpha_m",
            "α_m = 1 removes a_{1+α} from (13d)–(13e): the step equations are singular (need α_m ≠ 1)",
        ));
    }
    if c.r() > 1.0 {
        return Err(SpecError::new(
            "integrator.alpha_m",
            format!(
                "r = |α_m/(1 − α_m)| = {} > 1: the a, λ, ψ errors grow (Theorem 1 needs r < 1)",
                c.r()
            ),
        ));
    }
    if c.alpha_f == 1.0 {
        return Err(SpecError::new(
            "integrator.alpha_f",
            "α_f = 1 is excluded by Theorem 1 (need α_f ≠ 1)",
        ));
    }
    if c.beta == 0.0 {
        return Err(SpecError::new(
            "integrator.beta",
            "β = 0 is excluded by Theorem 1 (need β ≠ 0)",
        ));
    }
    if c.gamma == 0.0 {
        return Err(SpecError::new(
            "integrator.gamma",
            "γ = 0 is excluded by Theorem 1 (need γ ≠ 0)",
        ));
    }
    Ok(())
}

fn generalized_alpha_coefficients(p: &Soi2GeneralizedAlphaSpec) -> Result<Coefficients, SpecError> {
    let p = &p.coefficients;
    let explicit =
        p.alpha_m.is_some() || p.alpha_f.is_some() || p.beta.is_some() || p.gamma.is_some();
    let c = match (p.rho_inf, explicit) {
        (Some(_), true) => {
            return Err(SpecError::new(
                "integrator.rho_inf",
                "give rho_inf or alpha_m/alpha_f/beta/gamma, not both",
            ));
        }
        (rho, false) => {
            let rho = rho.unwrap_or(0.2);
            if !(rho.is_finite() && (0.0..=1.0).contains(&rho)) {
                return Err(SpecError::new(
                    "integrator.rho_inf",
                    format!("must be in [0, 1], got {rho}"),
                ));
            }
            Coefficients::from_rho_inf(rho)
        }
        (None, true) => {
            let alpha_m = p.alpha_m.ok_or_else(|| {
                SpecError::new("integrator.alpha_m", "missing (alpha_f is given)")
            })?;
            let alpha_f = p.alpha_f.ok_or_else(|| {
                SpecError::new("integrator.alpha_f", "missing (alpha_m is given)")
            })?;
            let alpha = alpha_m - alpha_f;
            Coefficients {
                alpha_m,
                alpha_f,
                beta: p.beta.unwrap_or((1.0 - alpha).powi(2) / 4.0),
                gamma: p.gamma.unwrap_or(0.5 - alpha),
            }
        }
    };
    check_coefficients(&c)?;
    Ok(c)
}

fn check_model<M: ConstrainedModel>(model: &M, tol: f64) -> Result<(), SpecError> {
    let iv = model.initial();
    check_constraint_rank(model, iv.t, &iv.y, &iv.z)
        .map_err(|e| SpecError::new("model", e.to_string()))?;
    check_consistency(model, tol).map_err(|e| SpecError::new("model", e.to_string()))
}

/// [`check_model`] for a user model, naming the spec field at fault: dependent joints
/// (`model.constraints`, unless the model declares `redundant_joints`), initial positions or
/// velocities that violate them (`model.q0`, `model.v0`).
fn check_user_model(model: &UserModel, tol: f64, redundant: bool) -> Result<(), SpecError> {
    let iv = model.initial();
    if !redundant {
        check_constraint_rank(model, iv.t, &iv.y, &iv.z).map_err(|e| {
            SpecError::new(
                "model.constraints",
                format!(
                    "{e}; if the joints are redundant on purpose, set `model.redundant_joints = true`"
                ),
            )
        })?;
    }
    check_consistency(model, tol).map_err(|e| {
        let field = match &e {
            Soi2Error::InconsistentInitialConditions {
                level: "velocity", ..
            } => "model.v0",
            _ => "model.q0",
        };
        SpecError::new(field, e.to_string())
    })
}

/// Builds the SOI2 job of a nonlinear constrained scene `model` (the dispatch in
/// [`crate::job::Job::from_spec`] has matched it with a SOI2 scheme; any other pair is refused
/// naming `integrator.scheme`). Checks the model's parameters, the rank of (g_y; k_z) and the
/// consistency of the initial values here, once.
pub(crate) fn soi2_job(model_spec: &ModelSpec, spec: &JobSpec) -> Result<Soi2Job, SpecError> {
    let model = match model_spec {
        ModelSpec::Pendulum(p) => Soi2Model::Pendulum(p.clone()),
        ModelSpec::SliderCrank(s) => Soi2Model::SliderCrank(s.clone()),
        ModelSpec::JayNegrutTest(j) => Soi2Model::JayNegrutTest(j.clone()),
        ModelSpec::Lagrangian(l) => {
            // The model first: its errors are reported whatever the scheme.
            let user = UserModel::new(l.validate()?);
            if !l.contacts.is_empty() {
                support::check(
                    spec.integrator.scheme(),
                    ModelFamily::Lagrangian,
                    Feature::Contacts,
                    "model.contacts",
                )?;
            }
            Soi2Model::User(Box::new(user))
        }
        _ => return Err(mismatch(model_spec, spec.integrator.scheme())),
    };
    let family = match &model {
        Soi2Model::User(_) => ModelFamily::Lagrangian,
        _ => ModelFamily::ConstrainedScene,
    };
    let steps = spec.time_section()?.steps(support::refusal(
        spec.integrator.scheme(),
        family,
        Feature::VariableStep,
        "",
    ))?;
    let schedule = Schedule {
        h: steps.h,
        pattern: steps.pattern,
        end: steps.end,
    };
    let adjust = steps.adjust;
    let (is_additive, has_nonholonomic, n) = match &model {
        Soi2Model::Pendulum(p) => {
            check_pendulum(p)?;
            (p.additive(), false, p.dims().n)
        }
        Soi2Model::SliderCrank(s) => {
            check_slider_crank(s)?;
            (s.additive(), false, s.dims().n)
        }
        Soi2Model::JayNegrutTest(j) => {
            check_jay_negrut_test(j)?;
            (j.additive(), true, j.dims().n)
        }
        Soi2Model::User(u) => (u.additive(), false, u.dims().n),
    };
    let (method, start, strategy, consistency) = match &spec.integrator {
        IntegratorSpec::Soi2GeneralizedAlpha(p) => {
            let coefficients = generalized_alpha_coefficients(p)?;
            let formulation = match p.additive {
                Some(true) if !is_additive => {
                    return Err(SpecError::new(
                        "integrator.additive",
                        "the model's forces are not of the form f₀ − g_yᵀλ − k_zᵀψ: use the general (13d)",
                    ));
                }
                Some(true) => Formulation::Additive,
                Some(false) => Formulation::General,
                None if is_additive => Formulation::Additive,
                None => Formulation::General,
            };
            let (newton, strategy, consistency) = newton_settings(&p.solve)?;
            (
                Method {
                    formulation,
                    coefficients,
                    newton,
                },
                p.start.into(),
                strategy,
                consistency,
            )
        }
        IntegratorSpec::Soi2Hht(p) | IntegratorSpec::HhtI3(p) => {
            let formulation = if matches!(spec.integrator, IntegratorSpec::Soi2Hht(_)) {
                Formulation::HhtSoi2
            } else {
                Formulation::HhtI3
            };
            if !(p.alpha.is_finite() && (-1.0 / 3.0..=0.0).contains(&p.alpha)) {
                return Err(SpecError::new(
                    "integrator.alpha",
                    format!("must be in [−1/3, 0], got {}", p.alpha),
                ));
            }
            if has_nonholonomic {
                support::check(spec.integrator.scheme(), family, Feature::Nonholonomic, "")?;
            }
            if !is_additive {
                return Err(SpecError::new(
                    "integrator.scheme",
                    format!(
                        "`{}` needs forces f₀ − g_yᵀλ; use soi2_generalized_alpha",
                        spec.integrator.scheme()
                    ),
                ));
            }
            let (newton, strategy, consistency) = newton_settings(&p.solve)?;
            (
                Method {
                    formulation,
                    coefficients: Coefficients::hht(p.alpha),
                    newton,
                },
                p.start.into(),
                strategy,
                consistency,
            )
        }
        _ => return Err(mismatch(model_spec, spec.integrator.scheme())),
    };
    match &model {
        Soi2Model::Pendulum(p) => check_model(p, consistency)?,
        Soi2Model::SliderCrank(s) => check_model(s, consistency)?,
        Soi2Model::JayNegrutTest(j) => check_model(j, consistency)?,
        Soi2Model::User(u) => {
            let redundant = matches!(model_spec, ModelSpec::Lagrangian(l) if l.redundant_joints);
            check_user_model(u, consistency, redundant)?
        }
    }
    let OutputOptions { every, probes } = spec.output.options(Probes::Dofs(n))?;
    let output = Soi2Output { every, probes };
    Ok(Soi2Job {
        model,
        method,
        start,
        newton: strategy,
        schedule,
        adjust,
        output,
    })
}

fn check_positive(field: &str, v: f64) -> Result<(), SpecError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(SpecError::new(
            format!("model.{field}"),
            format!("must be a finite number > 0, got {v}"),
        ))
    }
}

fn check_finite(field: &str, v: f64) -> Result<(), SpecError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(SpecError::new(
            format!("model.{field}"),
            format!("must be finite, got {v}"),
        ))
    }
}

fn check_override(field: &str, v: &Option<Vec<f64>>, n: usize) -> Result<(), SpecError> {
    if let Some(v) = v {
        if v.len() != n {
            return Err(SpecError::new(
                format!("model.{field}"),
                format!("needs {n} entries, got {}", v.len()),
            ));
        }
        if let Some(x) = v.iter().find(|x| !x.is_finite()) {
            return Err(SpecError::new(
                format!("model.{field}"),
                format!("entries must be finite, got {x}"),
            ));
        }
    }
    Ok(())
}

/// Checks the overrides' sizes.
fn check_jay_negrut_test(m: &JayNegrutTest) -> Result<(), SpecError> {
    check_override("y0", &m.y0, 2)?;
    check_override("z0", &m.z0, 2)
}

/// Checks the parameters.
fn check_pendulum(m: &Pendulum) -> Result<(), SpecError> {
    check_positive("mass", m.mass)?;
    check_positive("length", m.length)?;
    for (f, v) in [("stiffness", m.stiffness), ("damping", m.damping)] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(SpecError::new(
                format!("model.{f}"),
                format!("must be a finite number ≥ 0, got {v}"),
            ));
        }
    }
    for (f, v) in [
        ("gravity", m.gravity),
        ("theta0", m.theta0),
        ("omega0", m.omega0),
    ] {
        check_finite(f, v)?;
    }
    check_override("y0", &m.y0, 3)?;
    check_override("z0", &m.z0, 3)
}

/// Checks the parameters.
fn check_slider_crank(m: &SliderCrank) -> Result<(), SpecError> {
    for (f, v) in [
        ("crank_length", m.crank_length),
        ("crank_mass", m.crank_mass),
        ("rod_length", m.rod_length),
        ("rod_mass", m.rod_mass),
        ("slider_mass", m.slider_mass),
    ] {
        check_positive(f, v)?;
    }
    for (f, v) in [
        ("gravity", m.gravity),
        ("crank_angle", m.crank_angle),
        ("crank_speed", m.crank_speed),
    ] {
        check_finite(f, v)?;
    }
    if m.rod_length < m.crank_length {
        return Err(SpecError::new(
            "model.rod_length",
            format!(
                "must be ≥ crank_length ({}) for the crank to turn, got {}",
                m.crank_length, m.rod_length
            ),
        ));
    }
    Ok(())
}
