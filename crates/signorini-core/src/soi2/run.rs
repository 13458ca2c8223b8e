//! The SOI2 time loop (step-size patterns, (14) adjustments, energy and constraint streams)
//! and the job-spec side: integrator parameters, validation, summary.

use super::method::{
    self, Coefficients, Formulation, Method, NewtonCache, NewtonOptions, NewtonStrategy, Soi2State,
    StartValue,
};
use super::models::{JayNegrutTest, Pendulum, SliderCrank};
use super::{
    ConstrainedModel, GlobalErrors, Soi2Error, check_consistency, check_constraint_rank,
    constraint_residuals, dist2, kinetic_energy,
};
use crate::integrators::OutputOptions;
use crate::lagrangian::UserModel;
use crate::observer::{Columns, Observer, Progress, StepRecord};
use crate::outcome::Soi2Summary;
use crate::spec::{
    IntegratorSpec, JobSpec, ModelSpec, NewtonSpec, Probes, Soi2GeneralizedAlphaSpec,
    Soi2NewtonSpec, SpecError, StartSpec, mismatch,
};
use std::ops::ControlFlow;

// ---------------------------------------------------------------------------------------------
// Integrator specs (the types are in `crate::spec::integrator`)

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

impl From<NewtonStrategy> for NewtonSpec {
    fn from(s: NewtonStrategy) -> Self {
        match s {
            NewtonStrategy::Simplified => NewtonSpec::Simplified,
            NewtonStrategy::Full => NewtonSpec::Full,
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Step sizes

/// Step sizes of a run: `h · pattern[i mod len]` until `t_end` (the last step is shortened to
/// land on it) or for a number of steps.
#[derive(Debug, Clone, PartialEq)]
pub struct Schedule {
    /// Base step h.
    pub h: f64,
    /// Relative sizes, repeated (`[1]` for constant steps, `[1/3, 2/3]` for the paper's).
    pub pattern: Vec<f64>,
    /// Where to stop.
    pub end: End,
}

pub use crate::spec::End;

impl Schedule {
    /// The step sizes in order, generated one by one (a run never holds them all).
    pub fn iter(&self) -> impl Iterator<Item = f64> + '_ {
        let p = &self.pattern;
        let mut t = 0.0;
        let mut i = 0usize;
        std::iter::from_fn(move || {
            let hi = match self.end {
                End::Steps(n) if (i as u64) < n => self.h * p[i % p.len()],
                End::Steps(_) => return None,
                End::Time(t_end) => {
                    if t_end - t <= 1e-12 * self.h {
                        return None;
                    }
                    let hi = self.h * p[i % p.len()];
                    // Land exactly on t_end; never leave a sliver step behind.
                    if t + hi >= t_end - 1e-9 * self.h {
                        t_end - t
                    } else {
                        hi
                    }
                }
            };
            t += hi;
            i += 1;
            Some(hi)
        })
    }

    /// The step sizes in order, as a list.
    pub fn sizes(&self) -> Vec<f64> {
        self.iter().collect()
    }

    /// t_end / (h · mean relative step): the number of steps up to the last partial pattern
    /// period, in O(1) (no step is generated).
    pub fn estimated_steps(&self) -> f64 {
        match self.end {
            End::Steps(n) => n as f64,
            End::Time(t_end) => {
                let mean = self.pattern.iter().sum::<f64>() / self.pattern.len() as f64;
                t_end / (self.h * mean)
            }
        }
    }
}

/// Schedules of at most this many (estimated) steps are counted exactly by [`StepSizes::count`].
const COUNTED_STEPS: f64 = 1e7;

/// Where a run's step sizes come from: a list, or a [`Schedule`] that generates them lazily.
pub trait StepSizes {
    /// Number of steps, for progress reports and job limits: exact for a list and for a
    /// schedule of up to 10⁷ steps; beyond, [`Schedule::estimated_steps`] rounded up (within
    /// one pattern period of the count).
    fn count(&self) -> u64;
    /// The sizes in order.
    fn steps(&self) -> impl Iterator<Item = f64> + '_;
    /// True when the sizes vary (the variable-step path: a step whose Newton fails is rejected
    /// and retried with h/2); the last step, shortened to land on t_end, does not count.
    fn variable(&self) -> bool {
        let mut it = self.steps();
        let Some(first) = it.next() else {
            return false;
        };
        let mut it = it.peekable();
        while let Some(h) = it.next() {
            if h != first && it.peek().is_some() {
                return true;
            }
        }
        false
    }
}

impl StepSizes for [f64] {
    fn count(&self) -> u64 {
        self.len() as u64
    }
    fn steps(&self) -> impl Iterator<Item = f64> + '_ {
        self.iter().copied()
    }
}

impl StepSizes for Vec<f64> {
    fn count(&self) -> u64 {
        self.len() as u64
    }
    fn steps(&self) -> impl Iterator<Item = f64> + '_ {
        self.iter().copied()
    }
}

impl StepSizes for Schedule {
    fn count(&self) -> u64 {
        let estimate = self.estimated_steps();
        match self.end {
            End::Steps(n) => n,
            End::Time(_) if estimate <= COUNTED_STEPS => self.iter().count() as u64,
            End::Time(_) => estimate.ceil() as u64,
        }
    }
    fn steps(&self) -> impl Iterator<Item = f64> + '_ {
        self.iter()
    }
    fn variable(&self) -> bool {
        self.pattern.iter().any(|&p| p != self.pattern[0])
    }
}

// ---------------------------------------------------------------------------------------------
// Run loop

/// Output settings.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Soi2Output {
    /// Record every k-th step (≥ 1); the last is always recorded.
    pub every: u64,
    /// Coordinates j whose y_j, z_j are recorded.
    pub probes: Vec<usize>,
}

/// What a run measured over all its steps.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct Soi2Stats {
    /// Steps done.
    pub steps: u64,
    /// Final time.
    pub t_end: f64,
    /// Sum of Newton iterations.
    pub newton_iterations: u64,
    /// Largest Newton iteration count of a step.
    pub newton_iterations_max: usize,
    /// Newton Jacobians built (AD) for the steps; equals `newton_iterations` for full Newton.
    pub newton_jacobians: u64,
    /// max over steps of ‖g(t_n, y_n)‖∞.
    pub max_position_residual: f64,
    /// max over steps of ‖g_t + g_y z_n‖∞.
    pub max_velocity_residual: f64,
    /// max over steps of ‖k(t_n, y_n, z_n)‖∞.
    pub max_nonholonomic_residual: f64,
    /// Mechanical energy at t₀.
    pub energy_initial: f64,
    /// Mechanical energy at the end.
    pub energy_final: f64,
    /// Work of the damping forces.
    pub work_damping_total: f64,
    /// Global errors, for models with an exact solution.
    pub errors: Option<GlobalErrors>,
    /// Steps whose constraint Jacobian (g_y; k_z) had lost rank at y₁ (singular positions,
    /// redundant joints): solved by the minimum-norm path of [`super::factor`].
    #[serde(default)]
    pub rank_deficient_steps: u64,
    /// The smallest numerical rank of (g_y; k_z) seen on those steps.
    #[serde(default)]
    pub smallest_rank: Option<usize>,
    /// Attempts rejected for a Newton failure and retried with h/2 (variable-step runs).
    #[serde(default)]
    pub rejected_steps: u64,
}

/// Column names of a SOI2 run: the step h; the energies `kinetic` ½zᵀMz, `potential` V,
/// `energy` = kinetic + potential; `work_damping` (trapezoidal work of the damping forces, the
/// only non-conservative forces of a SOI2 model, over the step) and its running sum; `work_ext`,
/// the same work under the name the nonlinear models share (the applied non-conservative forces
/// `forces` of a `lagrangian` model); `energy_error` = E(t) − E(0) − Σ work_ext, the scheme's
/// energy error (it shrinks with h); the constraint residuals, Newton's iterations, λ, ψ and
/// the probes.
pub fn columns(dims: super::Dims, probes: &[usize]) -> Columns {
    let mut names: Vec<String> = [
        "h",
        "kinetic",
        "potential",
        "energy",
        "work_damping",
        "work_damping_total",
        "work_ext",
        "energy_error",
        "position_residual",
        "velocity_residual",
        "nonholonomic_residual",
        "newton_iterations",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    names.extend((0..dims.holonomic).map(|i| format!("lambda_{i}")));
    names.extend((0..dims.nonholonomic).map(|i| format!("psi_{i}")));
    for j in probes {
        names.extend([format!("y_{j}"), format!("z_{j}")]);
    }
    Columns::new(names)
}

/// Runs `model` with `method` over the step sizes `sizes`, adjusting a_α and M_α a_α by
/// (14a)–(14b) when `adjust`, and reporting to `observer`. Steps are solved by simplified
/// Newton ([`NewtonStrategy::Simplified`]); [`integrate_with`] chooses.
#[allow(clippy::too_many_arguments)]
pub fn integrate<M: ConstrainedModel + ?Sized, S: StepSizes + ?Sized>(
    model: &M,
    method: &Method,
    start: StartValue,
    sizes: &S,
    adjust: bool,
    output: &Soi2Output,
    observer: &mut dyn Observer,
) -> Result<(Soi2State, Soi2Stats), Soi2Error> {
    integrate_with(
        model,
        method,
        NewtonStrategy::default(),
        start,
        sizes,
        adjust,
        output,
        observer,
    )
}

/// [`integrate`] with the step Newton strategy `newton` (simplified or full).
#[allow(clippy::too_many_arguments)]
pub fn integrate_with<M: ConstrainedModel + ?Sized, S: StepSizes + ?Sized>(
    model: &M,
    method: &Method,
    newton: NewtonStrategy,
    start: StartValue,
    sizes: &S,
    adjust: bool,
    output: &Soi2Output,
    observer: &mut dyn Observer,
) -> Result<(Soi2State, Soi2Stats), Soi2Error> {
    integrate_from(
        model, method, newton, start, sizes, adjust, output, observer, None,
    )
}

/// What the SOI2 loop carries from one step to the next: the state (with a_α, M_α a_α and the
/// previous step's values that (14) interpolates from), the running statistics, the Newton
/// cache (the Jacobians' LU factors of simplified Newton), the damping force at t_k, the last
/// step size; the position in the step-size schedule is the step count.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(crate) struct Soi2Run {
    k: u64,
    state: Soi2State,
    stats: Soi2Stats,
    cache: NewtonCache,
    fd0: Vec<f64>,
    h_last: f64,
}

/// [`integrate_with`], or its continuation from a checkpoint's `resume`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn integrate_from<M: ConstrainedModel + ?Sized, S: StepSizes + ?Sized>(
    model: &M,
    method: &Method,
    newton: NewtonStrategy,
    start: StartValue,
    sizes: &S,
    adjust: bool,
    output: &Soi2Output,
    observer: &mut dyn Observer,
    resume: Option<&crate::checkpoint::Checkpoint>,
) -> Result<(Soi2State, Soi2Stats), Soi2Error> {
    let mut cache = NewtonCache::new(newton);
    let dims = model.dims();
    let n = dims.n;
    let alpha = method.coefficients.alpha();
    let cols = columns(dims, &output.probes);
    observer.start(&cols);
    let every = output.every.max(1);
    let total = sizes.count();
    let mut state =
        method::initial_state(model, method, start, sizes.steps().next().unwrap_or(1.0))?;
    let potential = |s: &Soi2State| model.potential(s.t, &s.y);
    let kinetic = |s: &Soi2State| kinetic_energy(model, s.t, &s.y, &s.z);
    let (k0, p0) = (kinetic(&state), potential(&state));
    let mut stats = Soi2Stats {
        t_end: state.t,
        energy_initial: k0 + p0,
        energy_final: k0 + p0,
        ..Default::default()
    };
    let e0 = k0 + p0;
    let mut row = Vec::with_capacity(cols.len());
    let mut fd0 = vec![0.0; n];
    let mut fd1 = vec![0.0; n];
    model.damping_force(state.t, &state.y, &state.z, &mut fd0);
    let record = |row: &mut Vec<f64>,
                  s: &Soi2State,
                  h: f64,
                  kin: f64,
                  pot: f64,
                  wd: f64,
                  wdt: f64,
                  res: [f64; 3],
                  it: usize| {
        row.clear();
        row.extend([
            h,
            kin,
            pot,
            kin + pot,
            wd,
            wdt,
            wd,
            kin + pot - e0 - wdt,
            res[0],
            res[1],
            res[2],
            it as f64,
        ]);
        row.extend_from_slice(&s.lambda);
        row.extend_from_slice(&s.psi);
        for &j in &output.probes {
            row.extend([s.y[j], s.z[j]]);
        }
    };
    let variable = sizes.variable();
    let mut steps = sizes.steps().peekable();
    let mut k = 0u64;
    let mut h_last = 0.0;
    match resume {
        Some(c) => {
            let run: Soi2Run = c.run_state(crate::checkpoint::RunKind::Soi2)?;
            if run.state.y.len() != n || run.fd0.len() != n {
                return Err(crate::checkpoint::CheckpointError::Mismatch(format!(
                    "a SOI2 state of {} coordinates, the model has {n}",
                    run.state.y.len()
                ))
                .into());
            }
            let r = run;
            (k, state, stats, cache, fd0, h_last) =
                (r.k, r.state, r.stats, r.cache, r.fd0, r.h_last);
            // The schedule's position: the k sizes already stepped.
            if k > 0 && steps.nth((k - 1) as usize).is_none() {
                return Err(crate::checkpoint::CheckpointError::Mismatch(format!(
                    "a checkpoint after step {k}, the schedule has fewer steps"
                ))
                .into());
            }
        }
        None => {
            let res0 = constraint_residuals(model, state.t, &state.y, &state.z);
            record(&mut row, &state, 0.0, k0, p0, 0.0, 0.0, res0, 0);
            if observer
                .observe(&StepRecord {
                    step: 0,
                    t: state.t,
                    values: &row,
                })
                .is_break()
            {
                return Err(Soi2Error::Stopped { step: 0 });
            }
        }
    }
    while let Some(h) = steps.next() {
        k += 1;
        h_last = h;
        let y_old = state.y.clone();
        // (14a)–(14b) when `adjust`; a rejected attempt retried with h/2 on variable steps.
        let info = method::advance(model, method, &mut state, h, &mut cache, adjust, variable)?;
        model.damping_force(state.t, &state.y, &state.z, &mut fd1);
        // Trapezoidal work of the damping forces over the step.
        let wd: f64 = (0..n)
            .map(|i| 0.5 * (fd0[i] + fd1[i]) * (state.y[i] - y_old[i]))
            .sum();
        std::mem::swap(&mut fd0, &mut fd1);
        stats.work_damping_total += wd;
        let res = constraint_residuals(model, state.t, &state.y, &state.z);
        stats.max_position_residual = stats.max_position_residual.max(res[0]);
        stats.max_velocity_residual = stats.max_velocity_residual.max(res[1]);
        stats.max_nonholonomic_residual = stats.max_nonholonomic_residual.max(res[2]);
        stats.newton_iterations += info.iterations as u64;
        stats.newton_iterations_max = stats.newton_iterations_max.max(info.iterations);
        stats.steps = k;
        stats.newton_jacobians = cache.jacobians;
        stats.rejected_steps += info.rejected;
        if let Some(rank) = info
            .rank
            .filter(|&r| r < dims.holonomic + dims.nonholonomic)
        {
            stats.rank_deficient_steps += 1;
            stats.smallest_rank = Some(stats.smallest_rank.map_or(rank, |s| s.min(rank)));
        }
        stats.t_end = state.t;
        if k.is_multiple_of(every) || steps.peek().is_none() {
            let (kin, pot) = (kinetic(&state), potential(&state));
            stats.energy_final = kin + pot;
            record(
                &mut row,
                &state,
                h,
                kin,
                pot,
                wd,
                stats.work_damping_total,
                res,
                info.iterations,
            );
            if observer
                .observe(&StepRecord {
                    step: k,
                    t: state.t,
                    values: &row,
                })
                .is_break()
            {
                return Err(Soi2Error::Stopped { step: k });
            }
        }
        let progress = Progress {
            done: k,
            total,
            t: state.t,
        };
        if let ControlFlow::Break(()) = observer.progress(progress) {
            return Err(Soi2Error::Stopped { step: k });
        }
        if observer.checkpoint_due(progress) {
            let run = Soi2Run {
                k,
                state: state.clone(),
                stats: stats.clone(),
                cache: cache.clone(),
                fd0: fd0.clone(),
                h_last,
            };
            let kind = crate::checkpoint::RunKind::Soi2;
            observer.checkpoint(&mut crate::checkpoint::Checkpoint::new(k, kind, &run)?);
        }
    }
    stats.errors = model.exact(state.t).map(|ex| {
        let a_ex = model
            .exact(state.t + alpha * h_last)
            .map(|e| e.a)
            .unwrap_or(ex.a);
        GlobalErrors {
            y: dist2(&state.y, &ex.y),
            z: dist2(&state.z, &ex.z),
            a: dist2(&state.a_alpha, &a_ex),
            lambda: dist2(&state.lambda, &ex.lambda),
            psi: dist2(&state.psi, &ex.psi),
        }
    });
    Ok((state, stats))
}

// ---------------------------------------------------------------------------------------------
// Jobs

/// A nonlinear constrained scene.
#[derive(Debug, Clone, PartialEq)]
pub enum Soi2Model {
    /// (16).
    Pendulum(Pendulum),
    /// Slider-crank.
    SliderCrank(SliderCrank),
    /// (15).
    JayNegrutTest(JayNegrutTest),
    /// A compiled `lagrangian` model (joints, no contacts).
    User(Box<UserModel>),
}

/// A validated SOI2 job.
#[derive(Debug, Clone, PartialEq)]
pub struct Soi2Job {
    /// The scene.
    pub model: Soi2Model,
    /// The method.
    pub method: Method,
    /// Start value of a_α.
    pub start: StartValue,
    /// Step Newton strategy (spec field `integrator.newton`).
    pub newton: NewtonStrategy,
    /// Step sizes.
    pub schedule: Schedule,
    /// Apply (14a)–(14b).
    pub adjust: bool,
    /// What to record.
    pub output: Soi2Output,
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
pub fn check_coefficients(c: &Coefficients) -> Result<(), SpecError> {
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

impl Soi2Job {
    /// Builds the SOI2 job of a nonlinear constrained scene `model` (the dispatch in
    /// [`crate::job::Job::from_spec`] has matched it with a SOI2 scheme; any other pair is refused
    /// naming `integrator.scheme`). Checks the model's parameters, the rank of (g_y; k_z) and the
    /// consistency of the initial values here, once.
    pub fn from_spec(model_spec: &ModelSpec, spec: &JobSpec) -> Result<Soi2Job, SpecError> {
        let model = match model_spec {
            ModelSpec::Pendulum(p) => Soi2Model::Pendulum(p.clone()),
            ModelSpec::SliderCrank(s) => Soi2Model::SliderCrank(s.clone()),
            ModelSpec::JayNegrutTest(j) => Soi2Model::JayNegrutTest(j.clone()),
            ModelSpec::Lagrangian(l) => {
                // The model first: its errors are reported whatever the scheme.
                let user = UserModel::new(l.validate()?);
                if !l.contacts.is_empty() {
                    return Err(SpecError::new(
                        "integrator.scheme",
                        format!(
                            "`{}` takes joints, not contacts: a lagrangian model with contacts runs with moreau_jean",
                            spec.integrator.scheme()
                        ),
                    ));
                }
                Soi2Model::User(Box::new(user))
            }
            _ => return Err(mismatch(model_spec, spec.integrator.scheme())),
        };
        let steps = spec.time_section()?.steps(true)?;
        let schedule = Schedule {
            h: steps.h,
            pattern: steps.pattern,
            end: steps.end,
        };
        let adjust = steps.adjust;
        let (is_additive, has_nonholonomic, n) = match &model {
            Soi2Model::Pendulum(p) => {
                p.validate()?;
                (p.additive(), false, p.dims().n)
            }
            Soi2Model::SliderCrank(s) => {
                s.validate()?;
                (s.additive(), false, s.dims().n)
            }
            Soi2Model::JayNegrutTest(j) => {
                j.validate()?;
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
                    return Err(SpecError::new(
                        "integrator.scheme",
                        format!(
                            "`{}` handles holonomic constraints only; this scene has nonholonomic ones: use soi2_generalized_alpha",
                            spec.integrator.scheme()
                        ),
                    ));
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
                let redundant =
                    matches!(model_spec, ModelSpec::Lagrangian(l) if l.redundant_joints);
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

    /// Number of steps ([`StepSizes::count`]: exact up to 10⁷).
    pub fn steps(&self) -> u64 {
        self.schedule.count()
    }

    /// Number of coordinates n.
    pub fn dofs(&self) -> usize {
        match &self.model {
            Soi2Model::Pendulum(p) => p.dims().n,
            Soi2Model::SliderCrank(s) => s.dims().n,
            Soi2Model::JayNegrutTest(j) => j.dims().n,
            Soi2Model::User(u) => u.dims().n,
        }
    }

    /// Number of recorded columns.
    pub fn columns(&self) -> usize {
        let d = match &self.model {
            Soi2Model::Pendulum(p) => p.dims(),
            Soi2Model::SliderCrank(s) => s.dims(),
            Soi2Model::JayNegrutTest(j) => j.dims(),
            Soi2Model::User(u) => u.dims(),
        };
        columns(d, &self.output.probes).len()
    }

    /// Runs the job; the summary's SOI2 part (the caller adds name, scene, scheme).
    pub fn run(&self, observer: &mut dyn Observer) -> Result<Soi2Summary, Soi2Error> {
        self.run_from(observer, None)
    }

    /// [`Soi2Job::run`], or its continuation from a checkpoint's `resume`.
    pub(crate) fn run_from(
        &self,
        observer: &mut dyn Observer,
        resume: Option<&crate::checkpoint::Checkpoint>,
    ) -> Result<Soi2Summary, Soi2Error> {
        let sizes = &self.schedule;
        let (state, stats) = match &self.model {
            Soi2Model::Pendulum(p) => integrate_from(
                p,
                &self.method,
                self.newton,
                self.start,
                sizes,
                self.adjust,
                &self.output,
                observer,
                resume,
            )?,
            Soi2Model::SliderCrank(s) => integrate_from(
                s,
                &self.method,
                self.newton,
                self.start,
                sizes,
                self.adjust,
                &self.output,
                observer,
                resume,
            )?,
            Soi2Model::JayNegrutTest(j) => integrate_from(
                j,
                &self.method,
                self.newton,
                self.start,
                sizes,
                self.adjust,
                &self.output,
                observer,
                resume,
            )?,
            Soi2Model::User(u) => integrate_from(
                u.as_ref(),
                &self.method,
                self.newton,
                self.start,
                sizes,
                self.adjust,
                &self.output,
                observer,
                resume,
            )?,
        };
        let c = self.method.coefficients;
        Ok(Soi2Summary {
            dofs: state.y.len(),
            holonomic_constraints: state.lambda.len(),
            nonholonomic_constraints: state.psi.len(),
            h: self.schedule.h,
            pattern: self.schedule.pattern.clone(),
            adjust: self.adjust,
            alpha_m: c.alpha_m,
            alpha_f: c.alpha_f,
            beta: c.beta,
            gamma: c.gamma,
            formulation: format!("{:?}", self.method.formulation),
            steps: stats.steps,
            t_end: stats.t_end,
            newton_iterations_total: stats.newton_iterations,
            newton_iterations_mean: if stats.steps > 0 {
                stats.newton_iterations as f64 / stats.steps as f64
            } else {
                0.0
            },
            newton_iterations_max: stats.newton_iterations_max,
            newton: NewtonSpec::from(self.newton).name().to_string(),
            newton_jacobians_total: stats.newton_jacobians,
            max_position_residual: stats.max_position_residual,
            max_velocity_residual: stats.max_velocity_residual,
            max_nonholonomic_residual: stats.max_nonholonomic_residual,
            energy_initial: stats.energy_initial,
            energy_final: stats.energy_final,
            work_damping_total: stats.work_damping_total,
            y_final: state.y,
            z_final: state.z,
            lambda_final: state.lambda,
            errors: stats.errors,
            rank_deficient_steps: stats.rank_deficient_steps,
            smallest_rank: stats.smallest_rank,
            rejected_steps: stats.rejected_steps,
        })
    }
}
