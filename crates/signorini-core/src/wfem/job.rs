//! Jobs on wave finite elements: time integration (`scheme = "wfem"`), nonsmooth modal analysis
//! and forced-response sweeps (`[analysis]`), validated at the edge (`crate::job`) into a
//! [`WaveJob`]; [`crate::job::Job::from_spec`] dispatches here.

use super::{StepTerms, WaveBar, WaveState, step};
use crate::checkpoint::{Checkpoint, CheckpointError, RunKind};
use crate::energy::{CUMULATIVE_COLUMNS, ENERGY_COLUMNS};
use crate::integrators::StepError;
use crate::modal::{self, ForcedResponseJob, ModalJob};
use crate::observer::{Columns, Observer};
use crate::outcome::{
    RunError, RunOutput, RunSummary, SummaryBody, SummaryHeader, WaveRunStats, WaveSummary,
};
use crate::stepping::{self, StepTime, StopReason, TimeStepping};

/// A validated job on wave finite elements.
#[derive(Debug, Clone)]
pub enum WaveJob {
    /// Time integration of a `bar`/`dep_bar` scene by Algorithm 2.
    Integrate {
        /// The bar.
        bar: WaveBar,
        /// Number of steps.
        steps: u64,
        /// Record every k-th step.
        every: u64,
    },
    /// Nonsmooth modal analysis (§§4–6).
    Modes(Box<ModalJob>),
    /// Forced-response sweep (§7).
    Forced(Box<ForcedResponseJob>),
}

impl WaveJob {
    /// (degrees of freedom, steps or tasks) for the service's limits.
    pub fn size(&self) -> (u64, u64) {
        match self {
            WaveJob::Integrate { bar, steps, .. } => (2 * bar.cells as u64, *steps),
            WaveJob::Modes(m) => (2 * m.cells as u64, m.tasks()),
            WaveJob::Forced(f) => (2 * f.cells as u64, f.tasks()),
        }
    }

    /// Whether this is an analysis (nonsmooth modes, forced response) rather than a time
    /// integration.
    pub fn is_analysis(&self) -> bool {
        !matches!(self, WaveJob::Integrate { .. })
    }

    /// Runs the job; `header` names it in the summary; an analysis spreads its tasks over
    /// `threads` threads.
    pub fn run(
        &self,
        header: SummaryHeader,
        threads: usize,
        observer: &mut dyn Observer,
    ) -> Result<RunOutput, RunError> {
        self.run_from(header, threads, observer, None)
    }

    /// [`WaveJob::run`], or the continuation of a time integration from a checkpoint's
    /// `resume` (an analysis has none).
    pub(crate) fn run_from(
        &self,
        header: SummaryHeader,
        threads: usize,
        observer: &mut dyn Observer,
        resume: Option<&Checkpoint>,
    ) -> Result<RunOutput, RunError> {
        match self {
            WaveJob::Integrate { bar, steps, every } => {
                let mut state = bar.initial_state();
                let stats = run_wave_from(bar, &mut state, *steps, *every, observer, resume)?;
                Ok(RunOutput {
                    summary: RunSummary::new(header, SummaryBody::Wave(stats.summary(bar))),
                    tables: Vec::new(),
                    charts: Vec::new(),
                })
            }
            WaveJob::Modes(_) | WaveJob::Forced(_) if resume.is_some() => {
                Err(CheckpointError::Unsupported("analysis").into())
            }
            WaveJob::Modes(m) => modal::run_modes(m, header, threads, observer),
            WaveJob::Forced(f) => modal::forced::run_forced(f, header, threads, observer),
        }
    }
}

/// Columns of a WFEM run: the energy terms, the cumulative works, `gap_0, u_0, p_0` (gap, gap
/// rate and contact impulse `−S σ* Δt ≥ 0` of the step), then `u_end` (contact-end displacement)
/// and `contact_force` (`r = S σ*`, (52), ≤ 0).
pub fn wave_columns() -> Columns {
    let mut names: Vec<String> = ENERGY_COLUMNS
        .iter()
        .chain(&CUMULATIVE_COLUMNS)
        .map(|s| s.to_string())
        .collect();
    names.extend(["gap_0", "u_0", "p_0", "u_end", "contact_force"].map(String::from));
    Columns::new(names)
}

impl WaveRunStats {
    fn summary(&self, bar: &WaveBar) -> WaveSummary {
        WaveSummary {
            cells: bar.cells,
            dofs: 2 * bar.cells,
            contacts: 1,
            h: bar.dt(),
            stats: self.clone(),
        }
    }
}

/// Runs `steps` steps of Algorithm 2 from `state`, recording every `every`-th step (and the
/// last). The work columns of a record sum the steps since the previous record, so
/// `balance_residual = ΔE − work_ext − work_damping − work_contact` over that interval
/// (per step with `every = 1`); WFEM has no numerical dissipation.
pub fn run_wave(
    bar: &WaveBar,
    state: &mut WaveState,
    steps: u64,
    every: u64,
    observer: &mut dyn Observer,
) -> Result<WaveRunStats, RunError> {
    run_wave_from(bar, state, steps, every, observer, None)
}

/// What the WFEM loop carries from one step to the next: the cells (the ring of characteristic
/// values) and end displacements, the running statistics, the energy of the last record, the
/// works summed since it and whether the gap was closed.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(crate) struct WaveRun {
    pub(crate) state: WaveState,
    stats: WaveRunStats,
    e_prev: f64,
    works: [f64; 3],
    was_contact: bool,
}

/// [`run_wave`], or its continuation from a checkpoint's `resume`.
pub(crate) fn run_wave_from(
    bar: &WaveBar,
    state: &mut WaveState,
    steps: u64,
    every: u64,
    observer: &mut dyn Observer,
    resume: Option<&Checkpoint>,
) -> Result<WaveRunStats, RunError> {
    let mut run = WaveStepping::new(bar, state, steps);
    match stepping::run(&mut run, every, observer, resume)? {
        StopReason::Finished { .. } => {
            let mut stats = run.stats;
            stats.steps = steps;
            stats.t_end = run.state.step as f64 * bar.dt();
            stats.energy_final = run.e_prev;
            Ok(stats)
        }
        StopReason::Observer { step } => Err(RunError::Stopped { step }),
    }
}

/// Algorithm 2 on a bar and its state, as [`stepping::run`] drives it: the memory of
/// [`WaveRun`] and the terms of the last step (which the next record reads).
struct WaveStepping<'a> {
    bar: &'a WaveBar,
    state: &'a mut WaveState,
    steps: u64,
    stats: WaveRunStats,
    e_prev: f64,
    works: [f64; 3],
    was_contact: bool,
    last: StepTerms,
}

impl<'a> WaveStepping<'a> {
    fn new(bar: &'a WaveBar, state: &'a mut WaveState, steps: u64) -> Self {
        let (kin, strain) = state.energies(bar);
        let e_prev = kin + strain;
        Self {
            bar,
            state,
            steps,
            stats: WaveRunStats {
                energy_initial: e_prev,
                energy_final: e_prev,
                ..Default::default()
            },
            e_prev,
            works: [0.0; 3],
            was_contact: false,
            last: StepTerms::default(),
        }
    }
}

impl TimeStepping for WaveStepping<'_> {
    type Memory = WaveRun;
    type Error = RunError;
    const RUN: RunKind = RunKind::Wave;

    fn columns(&self) -> Columns {
        wave_columns()
    }

    fn total_steps(&self) -> u64 {
        self.steps
    }

    fn is_done(&mut self, k: u64) -> bool {
        k >= self.steps
    }

    fn step(&mut self, _k: u64) -> Result<(), RunError> {
        let last = step(self.bar, self.state);
        let stats = &mut self.stats;
        self.works[0] += last.work_ext;
        self.works[1] += last.work_damping;
        self.works[2] += last.work_contact;
        stats.work_ext_total += last.work_ext;
        stats.work_damping_total += last.work_damping;
        stats.work_contact_total += last.work_contact;
        stats.closures += u64::from(last.contact && !self.was_contact);
        stats.contact_steps += u64::from(last.contact);
        self.was_contact = last.contact;
        self.last = last;
        Ok(())
    }

    fn now(&self) -> StepTime {
        StepTime {
            step: self.state.step,
            t: self.state.step as f64 * self.bar.dt(),
        }
    }

    /// The energies now, the works summed since the previous record and
    /// `balance_residual = ΔE − work_ext − work_damping − work_contact` over that interval.
    fn record(&mut self, row: &mut Vec<f64>) -> Result<(), RunError> {
        let (bar, state, terms) = (self.bar, &*self.state, &self.last);
        let dt = bar.dt();
        let (kin, strain) = state.energies(bar);
        let e = kin + strain;
        if !e.is_finite() || !state.u_right.is_finite() {
            return Err(StepError::NotFinite {
                step: state.step,
                t: state.step as f64 * dt,
            }
            .into());
        }
        let [w_ext, w_damp, w_contact] = self.works;
        let residual = (e - self.e_prev) - (w_ext + w_damp + w_contact);
        let stats = &mut self.stats;
        stats.max_abs_balance_residual = stats.max_abs_balance_residual.max(residual.abs());
        self.e_prev = e;
        row.clear();
        row.extend([kin, strain, e, w_ext, w_damp, w_contact, 0.0, e, residual]);
        row.extend([
            stats.work_ext_total,
            stats.work_damping_total,
            stats.work_contact_total,
        ]);
        let gap = bar.gap + bar.wall(state.step as f64 * dt) - state.u_right;
        row.extend([
            gap,
            terms.wall_velocity - terms.end_velocity,
            -bar.area * terms.contact_stress * dt,
            state.u_right,
            bar.area * terms.contact_stress,
        ]);
        self.works = [0.0; 3];
        Ok(())
    }

    fn memory(&self) -> WaveRun {
        WaveRun {
            state: self.state.clone(),
            stats: self.stats.clone(),
            e_prev: self.e_prev,
            works: self.works,
            was_contact: self.was_contact,
        }
    }

    fn restore(&mut self, run: WaveRun) -> Result<(), RunError> {
        if !run.state.fits(self.state) {
            return Err(CheckpointError::Mismatch(
                "a WFEM state of another number of cells".to_string(),
            )
            .into());
        }
        *self.state = run.state;
        self.stats = run.stats;
        self.e_prev = run.e_prev;
        self.works = run.works;
        self.was_contact = run.was_contact;
        Ok(())
    }
}
