//! The SOI2 time loop (step-size patterns, (14) adjustments, energy and constraint streams) on
//! the time-stepping driver, the validated job ([`Soi2Job`], built from the spec in
//! `crate::job`) and its summary.

use super::method::{self, Method, NewtonCache, NewtonStrategy, Soi2State, StartValue};
use super::models::{JayNegrutTest, Pendulum, SliderCrank};
use super::{
    ConstrainedModel, GlobalErrors, Soi2Error, constraint_residuals, dist2, kinetic_energy,
};
use crate::checkpoint::{Checkpoint, CheckpointError, RunKind};
use crate::lagrangian::UserModel;
use crate::observer::{Columns, Observer};
use crate::outcome::Soi2Summary;
use crate::spec::NewtonSpec;
use crate::stepping::{self, StepTime, StopReason, TimeStepping};

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
    /// Steps accepted on Newton's residual test while (g_y; k_z) kept its numerical rank: the
    /// near-singular steps next to a singular position, whose multipliers are determined only
    /// to cond(J)·ε (see [`super::method::NewtonOptions`]).
    #[serde(default)]
    pub near_singular_steps: u64,
}

/// Column names of a SOI2 run: the step h; the energies `kinetic` ½zᵀMz, `potential` V,
/// `energy` = kinetic + potential; `work_damping` (trapezoidal work of the damping forces, the
/// only non-conservative forces of a SOI2 model, over the step) and its running sum; `work_ext`,
/// the same work under the name the nonlinear models share (the applied non-conservative forces
/// `forces` of a `lagrangian` model); `energy_error` = E(t) − E(0) − Σ work_ext, the scheme's
/// energy error (it shrinks with h); the constraint residuals, Newton's iterations, λ, ψ and
/// the probes, named by `state` (positions, velocities: [`ConstrainedModel::state_names`]).
pub fn columns(
    dims: super::Dims,
    state: (&'static str, &'static str),
    probes: &[usize],
) -> Columns {
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
    let (position, velocity) = state;
    for j in probes {
        names.extend([format!("{position}_{j}"), format!("{velocity}_{j}")]);
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
    resume: Option<&Checkpoint>,
) -> Result<(Soi2State, Soi2Stats), Soi2Error> {
    let state = method::initial_state(model, method, start, sizes.steps().next().unwrap_or(1.0))?;
    let mut run = Soi2Stepping {
        model,
        method,
        adjust,
        variable: sizes.variable(),
        probes: &output.probes,
        total: sizes.count(),
        sizes: sizes.steps().peekable(),
        e0: 0.0,
        k: 0,
        res: constraint_residuals(model, state.t, &state.y, &state.z),
        stats: Soi2Stats::default(),
        cache: NewtonCache::new(newton),
        fd0: vec![0.0; state.y.len()],
        fd1: vec![0.0; state.y.len()],
        h: 0.0,
        h_last: 0.0,
        wd: 0.0,
        iterations: 0,
        state,
    };
    let e0 = run.kinetic() + run.potential();
    (run.e0, run.stats) = (
        e0,
        Soi2Stats {
            t_end: run.state.t,
            energy_initial: e0,
            energy_final: e0,
            ..Default::default()
        },
    );
    let s = &run.state;
    model.damping_force(s.t, &s.y, &s.z, &mut run.fd0);
    if let StopReason::Observer { step } = stepping::run(&mut run, output.every, observer, resume)?
    {
        return Err(Soi2Error::Stopped { step });
    }
    let (state, mut stats) = (run.state, run.stats);
    let alpha = method.coefficients.alpha();
    stats.errors = model.exact(state.t).map(|ex| {
        let a_ex = model
            .exact(state.t + alpha * run.h_last)
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

/// A SOI2 method on its model, state and step sizes, as [`stepping::run`] drives it: the memory
/// of [`Soi2Run`], the remaining step sizes (a step count or an end time; each step may have
/// its own h) and what the last step measured, for its record.
struct Soi2Stepping<'a, M: ?Sized, I: Iterator<Item = f64>> {
    model: &'a M,
    method: &'a Method,
    adjust: bool,
    /// A variable-step schedule: a step whose Newton fails is rejected and retried with h/2.
    variable: bool,
    probes: &'a [usize],
    total: u64,
    sizes: std::iter::Peekable<I>,
    /// Mechanical energy at t₀.
    e0: f64,
    k: u64,
    state: Soi2State,
    stats: Soi2Stats,
    cache: NewtonCache,
    /// Damping force at t_k.
    fd0: Vec<f64>,
    /// Damping force at t_{k+1} (scratch).
    fd1: Vec<f64>,
    /// The last step's h (0 before the first step), its damping work, constraint residuals and
    /// Newton iterations.
    h: f64,
    h_last: f64,
    wd: f64,
    res: [f64; 3],
    iterations: usize,
}

impl<M: ConstrainedModel + ?Sized, I: Iterator<Item = f64>> Soi2Stepping<'_, M, I> {
    fn kinetic(&self) -> f64 {
        let s = &self.state;
        kinetic_energy(self.model, s.t, &s.y, &s.z)
    }

    fn potential(&self) -> f64 {
        self.model.potential(self.state.t, &self.state.y)
    }
}

impl<M: ConstrainedModel + ?Sized, I: Iterator<Item = f64>> TimeStepping
    for Soi2Stepping<'_, M, I>
{
    type Memory = Soi2Run;
    type Error = Soi2Error;
    const RUN: RunKind = RunKind::Soi2;

    fn columns(&self) -> Columns {
        columns(self.model.dims(), self.model.state_names(), self.probes)
    }

    fn total_steps(&self) -> u64 {
        self.total
    }

    fn is_done(&mut self, _k: u64) -> bool {
        self.sizes.peek().is_none()
    }

    fn step(&mut self, k: u64) -> Result<(), Soi2Error> {
        // The driver steps only after `is_done` found a next size.
        let Some(h) = self.sizes.next() else {
            return Ok(());
        };
        let (model, state, stats) = (self.model, &mut self.state, &mut self.stats);
        self.k = k;
        self.h = h;
        self.h_last = h;
        let y_old = state.y.clone();
        // (14a)–(14b) when `adjust`; a rejected attempt retried with h/2 on variable steps.
        let info = method::advance(
            model,
            self.method,
            state,
            h,
            &mut self.cache,
            self.adjust,
            self.variable,
        )?;
        model.damping_force(state.t, &state.y, &state.z, &mut self.fd1);
        let (fd0, fd1) = (&self.fd0, &self.fd1);
        // Trapezoidal work of the damping forces over the step.
        let wd: f64 = (0..y_old.len())
            .map(|i| 0.5 * (fd0[i] + fd1[i]) * (state.y[i] - y_old[i]))
            .sum();
        std::mem::swap(&mut self.fd0, &mut self.fd1);
        self.wd = wd;
        stats.work_damping_total += wd;
        let res = constraint_residuals(model, state.t, &state.y, &state.z);
        self.res = res;
        stats.max_position_residual = stats.max_position_residual.max(res[0]);
        stats.max_velocity_residual = stats.max_velocity_residual.max(res[1]);
        stats.max_nonholonomic_residual = stats.max_nonholonomic_residual.max(res[2]);
        stats.newton_iterations += info.iterations as u64;
        stats.newton_iterations_max = stats.newton_iterations_max.max(info.iterations);
        self.iterations = info.iterations;
        stats.steps = k;
        stats.newton_jacobians = self.cache.jacobians;
        stats.rejected_steps += info.rejected;
        let d = model.dims();
        match info.rank {
            Some(rank) if rank < d.holonomic + d.nonholonomic => {
                stats.rank_deficient_steps += 1;
                stats.smallest_rank = Some(stats.smallest_rank.map_or(rank, |s| s.min(rank)));
            }
            Some(_) => stats.near_singular_steps += 1,
            None => {}
        }
        stats.t_end = state.t;
        Ok(())
    }

    fn now(&self) -> StepTime {
        StepTime {
            step: self.k,
            t: self.state.t,
        }
    }

    fn record(&mut self, row: &mut Vec<f64>) -> Result<(), Soi2Error> {
        let (kin, pot) = (self.kinetic(), self.potential());
        self.stats.energy_final = kin + pot;
        let (s, wd, wdt, res) = (
            &self.state,
            self.wd,
            self.stats.work_damping_total,
            self.res,
        );
        row.clear();
        row.extend([
            self.h,
            kin,
            pot,
            kin + pot,
            wd,
            wdt,
            wd,
            kin + pot - self.e0 - wdt,
            res[0],
            res[1],
            res[2],
            self.iterations as f64,
        ]);
        row.extend_from_slice(&s.lambda);
        row.extend_from_slice(&s.psi);
        for &j in self.probes {
            row.extend([s.y[j], s.z[j]]);
        }
        Ok(())
    }

    fn memory(&self) -> Soi2Run {
        Soi2Run {
            k: self.k,
            state: self.state.clone(),
            stats: self.stats.clone(),
            cache: self.cache.clone(),
            fd0: self.fd0.clone(),
            h_last: self.h_last,
        }
    }

    fn restore(&mut self, run: Soi2Run) -> Result<(), Soi2Error> {
        let n = self.state.y.len();
        if run.state.y.len() != n || run.fd0.len() != n {
            return Err(CheckpointError::Mismatch(format!(
                "a SOI2 state of {} coordinates, the model has {n}",
                run.state.y.len()
            ))
            .into());
        }
        let k = run.k;
        (
            self.k,
            self.state,
            self.stats,
            self.cache,
            self.fd0,
            self.h_last,
        ) = (k, run.state, run.stats, run.cache, run.fd0, run.h_last);
        // The schedule's position: the k sizes already stepped.
        if k > 0 && self.sizes.nth((k - 1) as usize).is_none() {
            return Err(CheckpointError::Mismatch(format!(
                "a checkpoint after step {k}, the schedule has fewer steps"
            ))
            .into());
        }
        Ok(())
    }
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

impl Soi2Job {
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
        let (d, names) = match &self.model {
            Soi2Model::Pendulum(p) => (p.dims(), p.state_names()),
            Soi2Model::SliderCrank(s) => (s.dims(), s.state_names()),
            Soi2Model::JayNegrutTest(j) => (j.dims(), j.state_names()),
            Soi2Model::User(u) => (u.dims(), u.state_names()),
        };
        columns(d, names, &self.output.probes).len()
    }

    /// Runs the job; the summary's SOI2 part (the caller adds name, scene, scheme).
    pub fn run(&self, observer: &mut dyn Observer) -> Result<Soi2Summary, Soi2Error> {
        self.run_from(observer, None)
    }

    /// [`Soi2Job::run`], or its continuation from a checkpoint's `resume`.
    pub(crate) fn run_from(
        &self,
        observer: &mut dyn Observer,
        resume: Option<&Checkpoint>,
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
            near_singular_steps: stats.near_singular_steps,
        })
    }
}
