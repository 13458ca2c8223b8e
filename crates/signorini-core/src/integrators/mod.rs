//! Time integrators of linear models with unilateral contact, and the run loop that drives any
//! of them, records energy terms and reports to an [`Observer`].
//!
//! A scheme holds only its run constants (factorisations, Delassus operator) and scratch
//! buffers; the state ([`LinearState`]) comes in explicitly, so a run can be paused and resumed.

pub mod alpha;
pub mod moreau_jean;
pub mod position_contact;

use crate::checkpoint::{Checkpoint, CheckpointError, RunKind};
use crate::contact::LcpStats;
use crate::energy::{CUMULATIVE_COLUMNS, ENERGY_COLUMNS, EnergyTerms};
use crate::friction::FrictionError;
use crate::lcp::LcpError;
use crate::model::LinearModel;
use crate::observer::{Columns, Observer};
use crate::stepping::{self, StepTime, StopReason, TimeStepping};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// State of a linear model at t_k.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LinearState {
    /// Step number k.
    pub step: u64,
    /// Time t_k.
    pub t: f64,
    /// Positions q_k.
    pub q: Vec<f64>,
    /// Velocities v_k.
    pub v: Vec<f64>,
}

impl LinearState {
    /// The model's initial state at t = 0.
    pub fn initial(model: &LinearModel) -> Self {
        Self {
            step: 0,
            t: 0.0,
            q: model.q0.clone(),
            v: model.v0.clone(),
        }
    }
}

/// What one step produced besides the new state.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct StepReport {
    /// Energy terms of the step.
    pub energy: EnergyTerms,
    /// Gap of each contact at t_{k+1}.
    pub gap: Vec<f64>,
    /// Local velocity U_{k+1} of each contact.
    pub local_velocity: Vec<f64>,
    /// Impulse P_{k+1} of each contact.
    pub impulse: Vec<f64>,
    /// Tangential impulse P_t,{k+1} of each contact (models with friction; zero otherwise).
    pub tangent_impulse: Vec<f64>,
    /// Tangential local velocity U_t,{k+1} = T v_{k+1} of each contact (models with friction).
    pub tangent_velocity: Vec<f64>,
    /// Discrete work of the friction impulses over the step (models with friction), included
    /// in `energy.balance_residual`.
    pub work_friction: f64,
    /// The step's LCP (or friction problem).
    pub lcp: LcpStats,
}

impl StepReport {
    /// A report sized for `contacts` contacts.
    pub fn with_contacts(contacts: usize) -> Self {
        Self {
            gap: vec![0.0; contacts],
            local_velocity: vec![0.0; contacts],
            impulse: vec![0.0; contacts],
            tangent_impulse: vec![0.0; contacts],
            tangent_velocity: vec![0.0; contacts],
            ..Default::default()
        }
    }

    /// Fills gaps and local velocities (with friction also the tangential ones) from the
    /// state at t.
    pub fn fill_contacts(&mut self, model: &LinearModel, q: &[f64], v: &[f64], t: f64) {
        for (a, c) in model.contacts.iter().enumerate() {
            self.gap[a] = c.gap(q, t);
            self.local_velocity[a] = c.local_velocity(v, t);
        }
        for (a, f) in model.friction.iter().enumerate() {
            self.tangent_velocity[a] = f.project(v);
        }
    }
}

/// Why a step failed.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum StepError {
    /// The contact LCP could not be solved to tolerance.
    #[error("step {step} (t = {t}): contact LCP failed: {source}")]
    Lcp {
        /// Step number (of the state reached).
        step: u64,
        /// Time t_{k+1}.
        t: f64,
        /// The solver's error.
        source: LcpError,
    },
    /// The friction problem of the step could not be solved to tolerance.
    #[error("step {step} (t = {t}): contact friction problem failed: {source}")]
    Friction {
        /// Step number (of the state reached).
        step: u64,
        /// Time t_{k+1}.
        t: f64,
        /// The solver's error.
        source: FrictionError,
    },
    /// The state became NaN or infinite.
    #[error("step {step} (t = {t}): the state is no longer finite")]
    NotFinite {
        /// Step number (of the state reached).
        step: u64,
        /// Time t_{k+1}.
        t: f64,
    },
}

/// A one-step method for a [`LinearModel`].
pub trait LinearScheme {
    /// Advances `state` by one step, writing the step's terms into `report`.
    fn step(
        &mut self,
        model: &LinearModel,
        state: &mut LinearState,
        report: &mut StepReport,
    ) -> Result<(), StepError>;

    /// The scheme's algorithmic energy H at `state` (the mechanical energy for Moreau–Jean).
    fn algorithmic_energy(&self, model: &LinearModel, state: &LinearState) -> f64;

    /// Step size h.
    fn step_size(&self) -> f64;

    /// What the scheme carries from one step to the next (history, cached values, index set),
    /// for a checkpoint; the rest it rebuilds from the model.
    fn save_state(&self) -> SchemeState;

    /// Restores a state saved by the same scheme, built for the same model and step size.
    fn restore_state(&mut self, state: SchemeState) -> Result<(), CheckpointError>;
}

/// What a linear scheme carries between steps, per scheme.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub enum SchemeState {
    /// [`moreau_jean::MoreauJean`].
    MoreauJean(Box<moreau_jean::MoreauJeanState>),
    /// [`alpha::NonsmoothAlpha`].
    Alpha(Box<alpha::AlphaState>),
    /// [`position_contact::PositionContact`].
    PositionContact(Box<alpha::AlphaCoreState>),
}

impl SchemeState {
    /// The refusal of a state saved by another scheme.
    fn mismatch(&self, expected: &str) -> CheckpointError {
        let found = match self {
            SchemeState::MoreauJean(_) => "moreau_jean",
            SchemeState::Alpha(_) => "the nonsmooth α-family",
            SchemeState::PositionContact(_) => "a position-contact scheme",
        };
        CheckpointError::Mismatch(format!("a state of {found}, not of {expected}"))
    }
}

/// What [`run_linear`] carries from one step to the next (the memory of a linear run, as a
/// checkpoint holds it): the state, the running statistics, the previous impulses (impact
/// count) and the scheme's state. The step's report is scratch: every scheme writes each of its
/// fields before the step's record reads them. A checkpoint written before the report was left
/// out (same state version, 1) holds it as one more field, which the decoder skips.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct LinearRun {
    pub(crate) state: LinearState,
    stats: LinearRunStats,
    previous_impulse: Vec<f64>,
    scheme: SchemeState,
}

/// Output settings of a run.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct OutputOptions {
    /// Record every k-th step (≥ 1); the last step is always recorded.
    pub every: u64,
    /// Dofs whose q_j, v_j are recorded.
    pub probes: Vec<usize>,
}

/// What a linear run measured over all its steps (recorded or not); its fields are those of
/// `summary.json`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct LinearRunStats {
    /// Steps done.
    pub steps: u64,
    /// Final time.
    pub t_end: f64,
    /// max_k |balance_residual|.
    pub max_abs_balance_residual: f64,
    /// Mechanical energy at t₀.
    pub energy_initial: f64,
    /// Mechanical energy at the end.
    pub energy_final: f64,
    /// Largest mechanical energy seen.
    pub energy_max: f64,
    /// Largest |algorithmic energy| seen.
    pub algorithmic_energy_max: f64,
    /// Impacts: (step, contact) pairs whose impulse became positive after a step without.
    pub impacts: u64,
    /// Largest LCP complementarity error.
    pub lcp_max_error: f64,
    /// Steps that solved a non-empty LCP.
    pub lcp_solves: u64,
    /// Cumulative works at the end: external, damping, contact.
    pub work_ext_total: f64,
    /// See `work_ext_total`.
    pub work_damping_total: f64,
    /// See `work_ext_total`.
    pub work_contact_total: f64,
    /// Cumulative friction work at the end (models with friction only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub work_friction_total: Option<f64>,
    /// Largest friction work of one step, max_k work_friction (models with friction only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub work_friction_max: Option<f64>,
}

/// The friction columns of a linear run whose model has friction, after the cumulative works:
/// the step's friction work and its cumulative sum.
pub const FRICTION_COLUMNS: [&str; 2] = ["work_friction", "work_friction_total"];

/// Column names of a linear run: energy terms, cumulative works, with friction
/// [`FRICTION_COLUMNS`], then `gap_α, u_α, p_α` per contact (with friction also `pt_α, ut_α`,
/// tangential impulse and velocity), then `q_j, v_j` per probe. A model without friction has
/// exactly the frictionless columns.
pub fn linear_columns(contacts: usize, friction: bool, probes: &[usize]) -> Columns {
    let mut names: Vec<String> = ENERGY_COLUMNS
        .iter()
        .chain(&CUMULATIVE_COLUMNS)
        .map(|s| s.to_string())
        .collect();
    if friction {
        names.extend(FRICTION_COLUMNS.iter().map(|s| s.to_string()));
    }
    for a in 0..contacts {
        names.extend([format!("gap_{a}"), format!("u_{a}"), format!("p_{a}")]);
        if friction {
            names.extend([format!("pt_{a}"), format!("ut_{a}")]);
        }
    }
    for j in probes {
        names.extend([format!("q_{j}"), format!("v_{j}")]);
    }
    Columns::new(names)
}

/// Why a run ended early.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum RunStop {
    /// A step failed.
    #[error(transparent)]
    Step(#[from] StepError),
    /// The observer asked to stop (cancellation) after `step` steps.
    #[error("stopped by the observer after {step} steps")]
    Stopped {
        /// Steps done.
        step: u64,
    },
    /// The checkpoint to resume from does not fit the run.
    #[error(transparent)]
    Checkpoint(#[from] CheckpointError),
}

/// Runs `steps` steps of `scheme` from `state`, recording per `output`.
pub fn run_linear(
    model: &LinearModel,
    scheme: &mut dyn LinearScheme,
    state: &mut LinearState,
    steps: u64,
    output: &OutputOptions,
    observer: &mut dyn Observer,
) -> Result<LinearRunStats, RunStop> {
    run_linear_from(model, scheme, state, steps, output, observer, None)
}

/// [`run_linear`], or its continuation from the checkpoint `resume` (then `state` and the
/// scheme's state are replaced by the checkpoint's, and the records up to it are not repeated;
/// a checkpoint of another run or scheme, or of another size, is refused before any step).
pub(crate) fn run_linear_from(
    model: &LinearModel,
    scheme: &mut dyn LinearScheme,
    state: &mut LinearState,
    steps: u64,
    output: &OutputOptions,
    observer: &mut dyn Observer,
    resume: Option<&Checkpoint>,
) -> Result<LinearRunStats, RunStop> {
    let mut run = LinearStepping::new(model, scheme, state, steps, &output.probes);
    match stepping::run(&mut run, output.every, observer, resume)? {
        StopReason::Finished { .. } => Ok(run.stats),
        StopReason::Observer { step } => Err(RunStop::Stopped { step }),
    }
}

/// A linear scheme on its model and state, as [`stepping::run`] drives it: the state, the
/// running statistics, the previous impulses (impact count) and the last step's report.
struct LinearStepping<'a> {
    model: &'a LinearModel,
    scheme: &'a mut dyn LinearScheme,
    state: &'a mut LinearState,
    steps: u64,
    probes: &'a [usize],
    friction: bool,
    report: StepReport,
    stats: LinearRunStats,
    previous_impulse: Vec<f64>,
}

impl<'a> LinearStepping<'a> {
    /// The run of `steps` steps from `state`, with its initial report and statistics.
    fn new(
        model: &'a LinearModel,
        scheme: &'a mut dyn LinearScheme,
        state: &'a mut LinearState,
        steps: u64,
        probes: &'a [usize],
    ) -> Self {
        let m = model.contacts.len();
        let friction = model.has_friction();
        let mut report = StepReport::with_contacts(m);
        report.fill_contacts(model, &state.q, &state.v, state.t);
        let (kin, strain) = model.energy(&state.q, &state.v);
        report.energy = EnergyTerms {
            kinetic: kin,
            strain,
            algorithmic_energy: scheme.algorithmic_energy(model, state),
            ..Default::default()
        };
        let e0 = kin + strain;
        let stats = LinearRunStats {
            t_end: state.t,
            energy_initial: e0,
            energy_final: e0,
            energy_max: e0,
            algorithmic_energy_max: report.energy.algorithmic_energy.abs(),
            work_friction_total: friction.then_some(0.0),
            ..Default::default()
        };
        Self {
            model,
            scheme,
            state,
            steps,
            probes,
            friction,
            report,
            stats,
            previous_impulse: vec![0.0; m],
        }
    }
}

impl TimeStepping for LinearStepping<'_> {
    type Memory = LinearRun;
    type Error = RunStop;
    const RUN: RunKind = RunKind::Linear;

    fn columns(&self) -> Columns {
        linear_columns(self.model.contacts.len(), self.friction, self.probes)
    }

    fn total_steps(&self) -> u64 {
        self.steps
    }

    fn is_done(&mut self, k: u64) -> bool {
        k >= self.steps
    }

    fn step(&mut self, k: u64) -> Result<(), RunStop> {
        let (state, report, stats) = (&mut *self.state, &mut self.report, &mut self.stats);
        self.scheme.step(self.model, state, report)?;
        let e = &report.energy;
        if !(e.energy().is_finite() && e.algorithmic_energy.is_finite()) {
            return Err(StepError::NotFinite {
                step: state.step,
                t: state.t,
            }
            .into());
        }
        stats.steps = k;
        stats.t_end = state.t;
        stats.work_ext_total += e.work_ext;
        stats.work_damping_total += e.work_damping;
        stats.work_contact_total += e.work_contact;
        if let Some(total) = stats.work_friction_total.as_mut() {
            *total += report.work_friction;
            stats.work_friction_max = Some(
                stats
                    .work_friction_max
                    .map_or(report.work_friction, |w| w.max(report.work_friction)),
            );
        }
        stats.max_abs_balance_residual =
            stats.max_abs_balance_residual.max(e.balance_residual.abs());
        stats.energy_final = e.energy();
        stats.energy_max = stats.energy_max.max(e.energy());
        stats.algorithmic_energy_max = stats.algorithmic_energy_max.max(e.algorithmic_energy.abs());
        stats.lcp_max_error = stats.lcp_max_error.max(report.lcp.error);
        stats.lcp_solves += u64::from(report.lcp.size > 0);
        stats.impacts += stepping::count_impacts(&mut self.previous_impulse, &report.impulse);
        Ok(())
    }

    fn now(&self) -> StepTime {
        StepTime {
            step: self.state.step,
            t: self.state.t,
        }
    }

    fn record(&mut self, row: &mut Vec<f64>) -> Result<(), RunStop> {
        let (report, stats, state) = (&self.report, &self.stats, &self.state);
        row.clear();
        row.extend_from_slice(&report.energy.values());
        row.extend([
            stats.work_ext_total,
            stats.work_damping_total,
            stats.work_contact_total,
        ]);
        if let Some(total) = stats.work_friction_total {
            row.extend([report.work_friction, total]);
        }
        for a in 0..self.model.contacts.len() {
            row.extend([report.gap[a], report.local_velocity[a], report.impulse[a]]);
            if self.friction {
                row.extend([report.tangent_impulse[a], report.tangent_velocity[a]]);
            }
        }
        for &j in self.probes {
            row.extend([state.q[j], state.v[j]]);
        }
        Ok(())
    }

    fn memory(&self) -> LinearRun {
        LinearRun {
            state: self.state.clone(),
            stats: self.stats.clone(),
            previous_impulse: self.previous_impulse.clone(),
            scheme: self.scheme.save_state(),
        }
    }

    fn restore(&mut self, run: LinearRun) -> Result<(), RunStop> {
        let m = self.model.contacts.len();
        if run.state.q.len() != self.state.q.len() || run.previous_impulse.len() != m {
            return Err(CheckpointError::Mismatch(format!(
                "a linear state of {} dofs, the model has {}",
                run.state.q.len(),
                self.state.q.len()
            ))
            .into());
        }
        self.scheme.restore_state(run.scheme)?;
        *self.state = run.state;
        self.stats = run.stats;
        self.previous_impulse = run.previous_impulse;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lcp::LcpOptions;
    use crate::scenes::BouncingBall;
    use moreau_jean::MoreauJean;

    /// A linear run's memory as state version 1 wrote it before the step's report was left out.
    #[derive(Serialize)]
    struct WithReport<'a> {
        state: &'a LinearState,
        stats: &'a LinearRunStats,
        previous_impulse: &'a [f64],
        report: &'a StepReport,
        scheme: &'a SchemeState,
    }

    /// The memory written with the report reads back to the memory without it, so the
    /// checkpoints written before keep loading under the same state version.
    #[test]
    fn a_memory_holding_the_last_report_still_reads() {
        let model = BouncingBall::default().build().unwrap();
        let mut scheme =
            MoreauJean::new(&model, Default::default(), 0.01, LcpOptions::default()).unwrap();
        let mut state = LinearState::initial(&model);
        let mut run = LinearStepping::new(&model, &mut scheme, &mut state, 300, &[]);
        for k in 1..=300 {
            run.step(k).unwrap();
        }
        assert!(run.stats.impacts > 0, "the ball bounced");
        let memory = run.memory();
        let old = rmp_serde::to_vec_named(&WithReport {
            state: &memory.state,
            stats: &memory.stats,
            previous_impulse: &memory.previous_impulse,
            report: &run.report,
            scheme: &memory.scheme,
        })
        .unwrap();
        let read: LinearRun = rmp_serde::from_slice(&old).unwrap();
        assert_eq!(
            rmp_serde::to_vec_named(&read).unwrap(),
            rmp_serde::to_vec_named(&memory).unwrap()
        );
    }
}
