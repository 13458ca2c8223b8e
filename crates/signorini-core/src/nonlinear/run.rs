//! A run of a user model as the time-stepping driver ([`stepping::run`]) drives it, for both
//! schemes of the module ([`super::moreau_jean`], [`super::generalized_alpha`]): the state, the
//! running statistics, the previous impulses (impact count), the Newton iterations summed and
//! the last step's report, around a scheme that says how to start, step, tally and record
//! ([`UserModelScheme`]); and what a checkpoint of it holds ([`UserModelRun`]).

use super::LagrangianSystem;
use super::generalized_alpha::{
    NonsmoothGeneralizedAlpha, NsAlphaMemory, NsAlphaRunStats, NsAlphaStepReport, ns_alpha_columns,
};
use super::joints::JointedSystem;
use super::moreau_jean::{
    MoreauJeanMemory, NonlinearMoreauJean, NonlinearRunStats, NonlinearRunStop, NonlinearState,
    NonlinearStepError, NonlinearStepReport, contact_values, has_friction, nonlinear_columns,
};
use crate::checkpoint::{Checkpoint, CheckpointError, RunKind};
use crate::dense::amax;
use crate::integrators::OutputOptions;
use crate::observer::{Columns, Observer};
use crate::stepping::{self, StepTime, StopReason, TimeStepping};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

/// A one-step scheme of user models, as [`run_user_model`] drives it.
pub(crate) trait UserModelScheme {
    /// What one step reports (energies, works, contacts, the scheme's own residuals).
    type Report;
    /// What the run measured over its steps (the summary's fields).
    type Stats: Clone + Serialize + DeserializeOwned;
    /// What the next step reads of the scheme besides the state.
    type Memory: Serialize + DeserializeOwned;
    /// The run a checkpoint of the scheme belongs to.
    const RUN: RunKind;
    /// The run, for errors: "a nonlinear", "an ns_generalized_alpha".
    const WHAT: &'static str;

    /// The recorded columns, those of the probes (`q_j`, `v_j`) last.
    fn columns<S: JointedSystem + ?Sized>(&self, system: &S, probes: &[usize]) -> Columns;

    /// The report of the initial state and the statistics of a run starting from it.
    fn start<S: JointedSystem + ?Sized>(
        &mut self,
        system: &S,
        state: &NonlinearState,
    ) -> (Self::Report, Self::Stats);

    /// Advances `state` by one step, writing `report`.
    fn step<S: JointedSystem + ?Sized>(
        &mut self,
        system: &S,
        state: &mut NonlinearState,
        report: &mut Self::Report,
    ) -> Result<(), NonlinearStepError>;

    /// The part of the report every user-model scheme has.
    fn base(report: &Self::Report) -> &NonlinearStepReport;

    /// The part of the statistics every user-model scheme has.
    fn base_stats(stats: &mut Self::Stats) -> &mut NonlinearRunStats;

    /// Adds the step's own figures (residuals, ranks) to the statistics, after the common ones.
    fn tally(stats: &mut Self::Stats, report: &Self::Report);

    /// Writes the values of the columns before the probes' into `row` (cleared).
    fn record<S: JointedSystem + ?Sized>(
        system: &S,
        report: &Self::Report,
        stats: &Self::Stats,
        row: &mut Vec<f64>,
    );

    /// The scheme's memory after the current step.
    fn memory(&self) -> Self::Memory;

    /// Replaces the scheme's memory by a checkpoint's; one that does not fit is refused.
    fn restore(&mut self, memory: Self::Memory) -> Result<(), CheckpointError>;
}

/// Runs `steps` steps of `scheme` on `system` from `state`, recording per `output` (every
/// `output.every`-th step and the last; a probe ≥ [`LagrangianSystem::dofs`] is refused).
pub fn run_nonlinear<S: JointedSystem + ?Sized>(
    system: &S,
    scheme: &mut NonlinearMoreauJean,
    state: &mut NonlinearState,
    steps: u64,
    output: &OutputOptions,
    observer: &mut dyn Observer,
) -> Result<NonlinearRunStats, NonlinearRunStop> {
    run_user_model(system, scheme, state, steps, output, observer, None)
}

/// Runs `steps` steps of `scheme` on `system` from `state`, recording per `output` (every
/// `output.every`-th step and the last; a probe ≥ the number of coordinates is refused).
pub fn run_ns_alpha<S: JointedSystem + ?Sized>(
    system: &S,
    scheme: &mut NonsmoothGeneralizedAlpha,
    state: &mut NonlinearState,
    steps: u64,
    output: &OutputOptions,
    observer: &mut dyn Observer,
) -> Result<NsAlphaRunStats, NonlinearRunStop> {
    run_user_model(system, scheme, state, steps, output, observer, None)
}

/// Runs `steps` steps of `scheme` on `system` from `state`, recording per `output` (every
/// `output.every`-th step and the last; a probe ≥ the number of coordinates is refused), or
/// continues the run from the checkpoint `resume`.
pub(crate) fn run_user_model<S: JointedSystem + ?Sized, M: UserModelScheme>(
    system: &S,
    scheme: &mut M,
    state: &mut NonlinearState,
    steps: u64,
    output: &OutputOptions,
    observer: &mut dyn Observer,
    resume: Option<&Checkpoint>,
) -> Result<M::Stats, NonlinearRunStop> {
    let n = system.dofs();
    if let Some(&probe) = output.probes.iter().find(|&&j| j >= n) {
        return Err(NonlinearRunStop::Probe { probe, dofs: n });
    }
    let (report, stats) = scheme.start(system, state);
    let mut run = UserModelStepping {
        previous_impulse: vec![0.0; system.contacts()],
        system,
        scheme,
        state,
        steps,
        probes: &output.probes,
        report,
        stats,
        newton_total: 0,
    };
    match stepping::run(&mut run, output.every, observer, resume)? {
        StopReason::Finished { .. } => Ok(run.stats),
        StopReason::Observer { step } => Err(NonlinearRunStop::Stopped { step }),
    }
}

/// A user-model scheme on its system and state, as [`stepping::run`] drives it.
struct UserModelStepping<'a, S: JointedSystem + ?Sized, M: UserModelScheme> {
    system: &'a S,
    scheme: &'a mut M,
    state: &'a mut NonlinearState,
    steps: u64,
    probes: &'a [usize],
    report: M::Report,
    stats: M::Stats,
    previous_impulse: Vec<f64>,
    newton_total: u64,
}

impl<S: JointedSystem + ?Sized, M: UserModelScheme> TimeStepping for UserModelStepping<'_, S, M> {
    type Memory = UserModelRun<M::Stats, M::Memory>;
    type Error = NonlinearRunStop;
    const RUN: RunKind = M::RUN;

    fn columns(&self) -> Columns {
        self.scheme.columns(self.system, self.probes)
    }

    fn total_steps(&self) -> u64 {
        self.steps
    }

    fn is_done(&mut self, k: u64) -> bool {
        k >= self.steps
    }

    fn step(&mut self, k: u64) -> Result<(), NonlinearRunStop> {
        self.scheme
            .step(self.system, self.state, &mut self.report)?;
        let base = M::base(&self.report);
        let stats = M::base_stats(&mut self.stats);
        stats.add_step(
            k,
            self.state.t,
            base,
            &mut self.newton_total,
            &mut self.previous_impulse,
        );
        stats.add_friction(base.work_friction);
        M::tally(&mut self.stats, &self.report);
        Ok(())
    }

    fn now(&self) -> StepTime {
        StepTime {
            step: self.state.step,
            t: self.state.t,
        }
    }

    fn record(&mut self, row: &mut Vec<f64>) -> Result<(), NonlinearRunStop> {
        row.clear();
        M::record(self.system, &self.report, &self.stats, row);
        for &j in self.probes {
            row.extend([self.state.q[j], self.state.v[j]]);
        }
        Ok(())
    }

    fn memory(&self) -> Self::Memory {
        UserModelRun {
            state: self.state.clone(),
            stats: self.stats.clone(),
            previous_impulse: self.previous_impulse.clone(),
            newton_total: self.newton_total,
            memory: self.scheme.memory(),
        }
    }

    fn restore(&mut self, run: Self::Memory) -> Result<(), NonlinearRunStop> {
        run.check_fits(M::WHAT, self.system)?;
        self.scheme.restore(run.memory)?;
        *self.state = run.state;
        self.stats = run.stats;
        self.previous_impulse = run.previous_impulse;
        self.newton_total = run.newton_total;
        Ok(())
    }
}

/// What a run of a user model carries from one step to the next, and all a checkpoint holds of
/// it: the state, the running statistics (`Stats`, the run's summary), the previous impulses
/// (the impact count), the Newton iterations summed (their mean) and the scheme's memory of the
/// end of the last step (`Memory`). The step's report is rebuilt by the next step and the
/// scheme's scratch (M, the iteration matrix, the Delassus operator) is never stored.
///
/// The fields are named as in state version 2 of both runs, whose checkpoints therefore keep
/// loading; a nonlinear Moreau–Jean checkpoint of that version also holds `work_friction_total`,
/// the sum `stats.work_friction_total` already holds, which the decoder skips.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct UserModelRun<Stats, Memory> {
    pub(crate) state: NonlinearState,
    pub(crate) stats: Stats,
    pub(crate) previous_impulse: Vec<f64>,
    pub(crate) newton_total: u64,
    pub(crate) memory: Memory,
}

impl<Stats, Memory> UserModelRun<Stats, Memory> {
    /// Refuses the run of `what` ("a nonlinear", "an ns_generalized_alpha") when its state or
    /// previous impulses do not have the sizes of `system`.
    pub(crate) fn check_fits<S: LagrangianSystem + ?Sized>(
        &self,
        what: &str,
        system: &S,
    ) -> Result<(), CheckpointError> {
        let (n, m) = (system.dofs(), system.contacts());
        if self.state.q.len() != n || self.previous_impulse.len() != m {
            return Err(CheckpointError::Mismatch(format!(
                "{what} state of {} coordinates and {} contacts, the system has {n} and {m}",
                self.state.q.len(),
                self.previous_impulse.len()
            )));
        }
        Ok(())
    }
}

impl UserModelScheme for NonlinearMoreauJean {
    type Report = NonlinearStepReport;
    type Stats = NonlinearRunStats;
    type Memory = MoreauJeanMemory;
    const RUN: RunKind = RunKind::Nonlinear;
    const WHAT: &'static str = "a nonlinear";

    fn columns<S: JointedSystem + ?Sized>(&self, system: &S, probes: &[usize]) -> Columns {
        nonlinear_columns(
            system.contacts(),
            has_friction(system),
            system.joints() > 0,
            probes,
        )
    }

    fn start<S: JointedSystem + ?Sized>(
        &mut self,
        system: &S,
        state: &NonlinearState,
    ) -> (NonlinearStepReport, NonlinearRunStats) {
        let mut report = NonlinearStepReport::of_state(system, state);
        let nb = system.joints();
        if nb > 0 {
            let mut g = vec![0.0; nb];
            system.joint_values(state.t, &state.q, &mut g);
            report.position_residual = amax(&g);
        }
        let stats = NonlinearRunStats {
            max_position_residual: (nb > 0).then_some(report.position_residual),
            ..NonlinearRunStats::starting(state.t, report.energy(), has_friction(system))
        };
        (report, stats)
    }

    fn step<S: JointedSystem + ?Sized>(
        &mut self,
        system: &S,
        state: &mut NonlinearState,
        report: &mut NonlinearStepReport,
    ) -> Result<(), NonlinearStepError> {
        self.step(system, state, report)
    }

    fn base(report: &NonlinearStepReport) -> &NonlinearStepReport {
        report
    }

    fn base_stats(stats: &mut NonlinearRunStats) -> &mut NonlinearRunStats {
        stats
    }

    fn tally(stats: &mut NonlinearRunStats, report: &NonlinearStepReport) {
        if let Some(r) = stats.max_position_residual.as_mut() {
            *r = r.max(report.position_residual);
        }
    }

    fn record<S: JointedSystem + ?Sized>(
        system: &S,
        report: &NonlinearStepReport,
        stats: &NonlinearRunStats,
        row: &mut Vec<f64>,
    ) {
        row.extend([
            report.kinetic,
            report.potential,
            report.energy(),
            report.work_ext,
            report.work_contact,
            report.energy_error,
            stats.work_ext_total,
            stats.work_contact_total,
            report.newton_iterations as f64,
        ]);
        if let Some(total) = stats.work_friction_total {
            row.extend([report.work_friction, total]);
        }
        contact_values(report, stats.work_friction_total.is_some(), row);
        if system.joints() > 0 {
            row.push(report.position_residual);
        }
    }

    fn memory(&self) -> MoreauJeanMemory {
        self.memory().clone()
    }

    fn restore(&mut self, memory: MoreauJeanMemory) -> Result<(), CheckpointError> {
        self.restore(memory)
    }
}

impl UserModelScheme for NonsmoothGeneralizedAlpha {
    type Report = NsAlphaStepReport;
    type Stats = NsAlphaRunStats;
    type Memory = Option<NsAlphaMemory>;
    const RUN: RunKind = RunKind::NsAlpha;
    const WHAT: &'static str = "an ns_generalized_alpha";

    fn columns<S: JointedSystem + ?Sized>(&self, system: &S, probes: &[usize]) -> Columns {
        ns_alpha_columns(system.contacts(), self.friction, system.joints(), probes)
    }

    /// The report of the initial state carries the multipliers of the consistent start.
    fn start<S: JointedSystem + ?Sized>(
        &mut self,
        system: &S,
        state: &NonlinearState,
    ) -> (NsAlphaStepReport, NsAlphaRunStats) {
        let mut report = NsAlphaStepReport::of_state(system, state);
        if system.joints() > 0 {
            // The multipliers of the start, from the consistent accelerations.
            if let Some((_, lambda, _)) = self.consistent(system, state.t, &state.q, &state.v) {
                report.lambda = lambda;
            }
        }
        let stats = NsAlphaRunStats {
            base: NonlinearRunStats::starting(state.t, report.base.energy(), self.friction),
            max_position_residual: report.position_residual,
            max_velocity_residual: report.velocity_residual,
            max_penetration: report.penetration,
            ..Default::default()
        };
        (report, stats)
    }

    fn step<S: JointedSystem + ?Sized>(
        &mut self,
        system: &S,
        state: &mut NonlinearState,
        report: &mut NsAlphaStepReport,
    ) -> Result<(), NonlinearStepError> {
        self.step(system, state, report)
    }

    fn base(report: &NsAlphaStepReport) -> &NonlinearStepReport {
        &report.base
    }

    fn base_stats(stats: &mut NsAlphaRunStats) -> &mut NonlinearRunStats {
        &mut stats.base
    }

    fn tally(stats: &mut NsAlphaRunStats, report: &NsAlphaStepReport) {
        stats.max_position_residual = stats.max_position_residual.max(report.position_residual);
        stats.max_velocity_residual = stats.max_velocity_residual.max(report.velocity_residual);
        stats.max_penetration = stats.max_penetration.max(report.penetration);
        stats.position_iterations_max = stats
            .position_iterations_max
            .max(report.position_iterations);
        stats.newton_jacobians_total += report.newton_matrices as u64;
        if let Some(rank) = report.joint_rank {
            stats.rank_deficient_steps += 1;
            stats.smallest_rank = Some(stats.smallest_rank.map_or(rank, |s| s.min(rank)));
        }
    }

    fn record<S: JointedSystem + ?Sized>(
        _system: &S,
        r: &NsAlphaStepReport,
        stats: &NsAlphaRunStats,
        row: &mut Vec<f64>,
    ) {
        let b = &r.base;
        row.extend([
            b.kinetic,
            b.potential,
            b.energy(),
            b.work_ext,
            b.work_contact,
            b.work_friction,
            b.energy_error,
            stats.base.work_ext_total,
            stats.base.work_contact_total,
        ]);
        let friction = stats.base.work_friction_total;
        row.extend(friction);
        row.extend([b.newton_iterations as f64, r.position_iterations as f64]);
        contact_values(b, friction.is_some(), row);
        row.extend_from_slice(&r.lambda);
        row.extend([r.position_residual, r.velocity_residual]);
    }

    fn memory(&self) -> Option<NsAlphaMemory> {
        self.memory().cloned()
    }

    fn restore(&mut self, memory: Option<NsAlphaMemory>) -> Result<(), CheckpointError> {
        self.restore(memory)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A nonlinear Moreau–Jean run's memory as state version 2 wrote it, with the friction sum
    /// kept twice.
    #[derive(Serialize)]
    struct WithSum {
        state: NonlinearState,
        stats: NonlinearRunStats,
        previous_impulse: Vec<f64>,
        newton_total: u64,
        work_friction_total: f64,
        memory: Vec<f64>,
    }

    #[test]
    fn a_memory_holding_the_friction_sum_twice_still_reads() {
        let stats = NonlinearRunStats {
            steps: 7,
            work_friction_total: Some(-0.25),
            ..Default::default()
        };
        let old = WithSum {
            state: NonlinearState {
                step: 7,
                t: 0.07,
                q: vec![1.0, 2.0],
                v: vec![-3.0, 0.5],
            },
            stats: stats.clone(),
            previous_impulse: vec![0.0, 4.0],
            newton_total: 15,
            work_friction_total: -0.25,
            memory: vec![9.0],
        };
        let bytes = rmp_serde::to_vec_named(&old).unwrap();
        let read: UserModelRun<NonlinearRunStats, Vec<f64>> =
            rmp_serde::from_slice(&bytes).unwrap();
        assert_eq!(read.state, old.state);
        assert_eq!(read.stats, stats);
        assert_eq!(read.previous_impulse, old.previous_impulse);
        assert_eq!(read.newton_total, 15);
        assert_eq!(read.memory, old.memory);
    }
}
