//! Jobs on wave finite elements: time integration (`scheme = "wfem"`), nonsmooth modal analysis
//! and forced-response sweeps (`[analysis]`). [`crate::job::Job::from_spec`] dispatches here.

use super::{WaveBar, WaveState, step};
use crate::energy::{CUMULATIVE_COLUMNS, ENERGY_COLUMNS};
use crate::integrators::StepError;
use crate::modal::{self, ForcedResponseJob, ModalJob};
use crate::observer::{Columns, Observer, Progress, StepRecord};
use crate::outcome::{
    RunError, RunOutput, RunSummary, SummaryBody, SummaryHeader, WaveRunStats, WaveSummary,
};
use crate::scenes::Bar;
use crate::spec::{AnalysisSpec, JobSpec, ModelSpec, Probes, SpecError};
use std::ops::ControlFlow;

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
    /// The job of an `[analysis]` section.
    pub fn analysis(analysis: &AnalysisSpec) -> Result<WaveJob, SpecError> {
        Ok(match analysis {
            AnalysisSpec::NonsmoothModes(m) => WaveJob::Modes(Box::new(ModalJob::from_spec(m)?)),
            AnalysisSpec::ForcedResponse(f) => {
                WaveJob::Forced(Box::new(ForcedResponseJob::from_spec(f)?))
            }
        })
    }

    /// Time integration (`scheme = "wfem"`) of the `bar` or `dep_bar` scene `model`.
    pub fn integrate(model: &ModelSpec, spec: &JobSpec) -> Result<WaveJob, SpecError> {
        if let ModelSpec::Bar(b) | ModelSpec::DepBar(b) = model
            && b.obstacle.is_some()
        {
            return Err(SpecError::new(
                "model.obstacle",
                "scheme \"wfem\" takes the bar's end contact only: run a distributed obstacle with moreau_jean or the nonsmooth α-family",
            ));
        }
        let bar = match model {
            ModelSpec::Bar(b) => b.resolve(Bar::default()),
            ModelSpec::DepBar(b) => b.resolve(Bar::doyen_ern_piperno(100)),
            other => {
                return Err(SpecError::new(
                    "model.scene",
                    format!(
                        "scheme \"wfem\" runs the scenes \"bar\" and \"dep_bar\", not \"{}\"",
                        other.scene()
                    ),
                ));
            }
        };
        let bar = WaveBar::from_bar(&bar).map_err(|e| match e {
            super::WfemError::OutOfRange { field, .. }
            | super::WfemError::Unsupported { field, .. } => {
                SpecError::new(format!("model.{field}"), e.to_string())
            }
        })?;
        let time = spec.time_section()?;
        let dt = bar.dt();
        if !(time.h.is_finite() && (time.h - dt).abs() <= 1e-6 * dt) {
            return Err(SpecError::new(
                "time.h",
                format!(
                    "wave finite elements step by Δt = Δx/c = {dt:e} exactly (cells = elements), got {}",
                    time.h
                ),
            ));
        }
        let steps = time.steps(false)?.count();
        let output = spec.output.options(Probes::Unsupported(
            "wave finite elements record the contact end; probes are not supported",
        ))?;
        Ok(WaveJob::Integrate {
            bar,
            steps,
            every: output.every,
        })
    }

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
        resume: Option<&crate::checkpoint::Checkpoint>,
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
                Err(crate::checkpoint::CheckpointError::Unsupported("analysis").into())
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
    resume: Option<&crate::checkpoint::Checkpoint>,
) -> Result<WaveRunStats, RunError> {
    let columns = wave_columns();
    observer.start(&columns);
    let every = every.max(1);
    let dt = bar.dt();
    let (kin, strain) = state.energies(bar);
    let mut e_prev = kin + strain;
    let mut stats = WaveRunStats {
        energy_initial: e_prev,
        energy_final: e_prev,
        ..Default::default()
    };
    let mut row = Vec::with_capacity(columns.len());
    let (mut w_ext, mut w_damp, mut w_contact) = (0.0, 0.0, 0.0);
    let mut last = super::StepTerms::default();
    let mut was_contact = false;
    let push_row = |row: &mut Vec<f64>,
                    kin: f64,
                    strain: f64,
                    works: [f64; 3],
                    residual: f64,
                    totals: [f64; 3],
                    state: &WaveState,
                    terms: &super::StepTerms| {
        row.clear();
        row.extend([
            kin,
            strain,
            kin + strain,
            works[0],
            works[1],
            works[2],
            0.0,
            kin + strain,
            residual,
        ]);
        row.extend(totals);
        let gap = bar.gap + bar.wall(state.step as f64 * dt) - state.u_right;
        row.extend([
            gap,
            terms.wall_velocity - terms.end_velocity,
            -bar.area * terms.contact_stress * dt,
            state.u_right,
            bar.area * terms.contact_stress,
        ]);
    };
    let first = match resume {
        Some(c) => {
            let run: WaveRun = c.run_state(crate::checkpoint::RunKind::Wave)?;
            if !run.state.fits(state) {
                return Err(crate::checkpoint::CheckpointError::Mismatch(
                    "a WFEM state of another number of cells".to_string(),
                )
                .into());
            }
            let r = run;
            let k = r.state.step;
            (*state, stats, e_prev, was_contact) = (r.state, r.stats, r.e_prev, r.was_contact);
            [w_ext, w_damp, w_contact] = r.works;
            k + 1
        }
        None => {
            push_row(&mut row, kin, strain, [0.0; 3], 0.0, [0.0; 3], state, &last);
            if observer
                .observe(&StepRecord {
                    step: state.step,
                    t: state.step as f64 * dt,
                    values: &row,
                })
                .is_break()
            {
                return Err(RunError::Stopped { step: 0 });
            }
            1
        }
    };
    for k in first..=steps {
        last = step(bar, state);
        w_ext += last.work_ext;
        w_damp += last.work_damping;
        w_contact += last.work_contact;
        stats.work_ext_total += last.work_ext;
        stats.work_damping_total += last.work_damping;
        stats.work_contact_total += last.work_contact;
        stats.closures += u64::from(last.contact && !was_contact);
        stats.contact_steps += u64::from(last.contact);
        was_contact = last.contact;
        if k % every == 0 || k == steps {
            let (kin, strain) = state.energies(bar);
            let e = kin + strain;
            if !e.is_finite() || !state.u_right.is_finite() {
                return Err(StepError::NotFinite {
                    step: state.step,
                    t: state.step as f64 * dt,
                }
                .into());
            }
            let residual = (e - e_prev) - (w_ext + w_damp + w_contact);
            stats.max_abs_balance_residual = stats.max_abs_balance_residual.max(residual.abs());
            e_prev = e;
            let totals = [
                stats.work_ext_total,
                stats.work_damping_total,
                stats.work_contact_total,
            ];
            push_row(
                &mut row,
                kin,
                strain,
                [w_ext, w_damp, w_contact],
                residual,
                totals,
                state,
                &last,
            );
            (w_ext, w_damp, w_contact) = (0.0, 0.0, 0.0);
            if observer
                .observe(&StepRecord {
                    step: state.step,
                    t: state.step as f64 * dt,
                    values: &row,
                })
                .is_break()
            {
                return Err(RunError::Stopped { step: k });
            }
        }
        let progress = Progress {
            done: k,
            total: steps,
            t: state.step as f64 * dt,
        };
        if let ControlFlow::Break(()) = observer.progress(progress) {
            return Err(RunError::Stopped { step: k });
        }
        if observer.checkpoint_due(progress) {
            let run = WaveRun {
                state: state.clone(),
                stats: stats.clone(),
                e_prev,
                works: [w_ext, w_damp, w_contact],
                was_contact,
            };
            let kind = crate::checkpoint::RunKind::Wave;
            observer.checkpoint(&mut crate::checkpoint::Checkpoint::new(k, kind, &run)?);
        }
    }
    stats.steps = steps;
    stats.t_end = state.step as f64 * dt;
    stats.energy_final = e_prev;
    Ok(stats)
}
