//! Time stepping: the one loop that drives every time integration of the core.
//!
//! A family of schemes (the linear schemes, WFEM, SOI2, the nonlinear time-stepping of user
//! models) implements [`TimeStepping`]: one step on its state, the row of values it records, and
//! its *memory* — what the next step reads (state, running statistics, the scheme's history),
//! apart from its scratch buffers. [`run`] owns what every run shares, in the order Siconos'
//! `TimeStepping::run` and diffsol's `step() -> StopReason` give it: the initial record, a record
//! every `every`-th step and at the last one, [`Observer::progress`] after every step, a
//! [`Checkpoint`] of the memory when [`Observer::checkpoint_due`] says so, the observer's stop,
//! and the reason the run ended ([`StopReason`]), which callers read instead of inferring it.
//!
//! A checkpoint holds the memory as the family's own serde type ([`TimeStepping::Memory`]) inside
//! the versioned, checksummed envelope of [`crate::checkpoint`]; [`run`] continued from it
//! restores the memory and repeats no record.

use crate::checkpoint::{Checkpoint, CheckpointError, RunKind};
use crate::observer::{Columns, Observer, Progress, StepRecord};
use serde::Serialize;
use serde::de::DeserializeOwned;

/// Step number and time of a family's current state (the fields of its [`StepRecord`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepTime {
    /// Step number; 0 is the initial state.
    pub step: u64,
    /// Time t_k.
    pub t: f64,
}

/// A family of one-step methods as [`run`] drives it: the scheme with its model, state and
/// running statistics.
pub trait TimeStepping {
    /// What the next step reads and a checkpoint holds: the state, the running statistics and
    /// the scheme's history, never scratch buffers nor anything rebuilt from the job.
    type Memory: Serialize + DeserializeOwned;
    /// Why a step, a record or a restore failed.
    type Error: From<CheckpointError>;
    /// The run a checkpoint of this family belongs to.
    const RUN: RunKind;

    /// The names of the recorded values, fixed before the first step.
    fn columns(&self) -> Columns;

    /// Steps of the whole run, for [`Progress::total`] (a variable-step run ending at a time may
    /// estimate it).
    fn total_steps(&self) -> u64;

    /// Whether the run ends after `k` steps (a step count or the end time reached).
    fn is_done(&mut self, k: u64) -> bool;

    /// Advances the state by step `k` (the first step is 1), updating the running statistics.
    fn step(&mut self, k: u64) -> Result<(), Self::Error>;

    /// Step number and time of the current state.
    fn now(&self) -> StepTime;

    /// Writes the current state's row (one value per column) into `row`, cleared first. A family
    /// whose records sum terms since the previous record (WFEM) closes that interval here.
    fn record(&mut self, row: &mut Vec<f64>) -> Result<(), Self::Error>;

    /// The memory after the current step, for a checkpoint.
    fn memory(&self) -> Self::Memory;

    /// Replaces the state, statistics and scheme history by a checkpoint's memory; a memory that
    /// does not fit (another size, another scheme) is refused before anything is replaced.
    fn restore(&mut self, memory: Self::Memory) -> Result<(), Self::Error>;
}

/// Why [`run`] ended without an error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopReason {
    /// Every step was done.
    Finished {
        /// Steps done in all (those before a resumed checkpoint included).
        steps: u64,
    },
    /// The observer asked to stop (cancellation) after `step` steps.
    Observer {
        /// Steps done.
        step: u64,
    },
}

/// Runs `family` to its end, recording every `every`-th step (≥ 1; 0 counts as 1) and the last
/// one, or continues it from the checkpoint `resume` (its memory restored, the records up to it
/// not repeated; a checkpoint of another run is refused before any step). Returns why the run
/// ended; a failed step or a refused checkpoint is the error.
pub fn run<F: TimeStepping + ?Sized>(
    family: &mut F,
    every: u64,
    observer: &mut dyn Observer,
    resume: Option<&Checkpoint>,
) -> Result<StopReason, F::Error> {
    let columns = family.columns();
    observer.start(&columns);
    let every = every.max(1);
    let total = family.total_steps();
    let mut row = Vec::with_capacity(columns.len());
    let mut k = match resume {
        Some(c) => {
            family.restore(c.run_state(F::RUN)?)?;
            c.step()
        }
        None => {
            if record(family, &mut row, observer)?.is_break() {
                return Ok(StopReason::Observer { step: 0 });
            }
            0
        }
    };
    while !family.is_done(k) {
        k += 1;
        family.step(k)?;
        if (k.is_multiple_of(every) || family.is_done(k))
            && record(family, &mut row, observer)?.is_break()
        {
            return Ok(StopReason::Observer { step: k });
        }
        let progress = Progress {
            done: k,
            total,
            t: family.now().t,
        };
        if observer.progress(progress).is_break() {
            return Ok(StopReason::Observer { step: k });
        }
        if observer.checkpoint_due(progress) {
            let memory = family.memory();
            observer.checkpoint(&mut Checkpoint::new(k, F::RUN, &memory)?);
        }
    }
    Ok(StopReason::Finished { steps: k })
}

/// Hands the current row to the observer.
fn record<F: TimeStepping + ?Sized>(
    family: &mut F,
    row: &mut Vec<f64>,
    observer: &mut dyn Observer,
) -> Result<std::ops::ControlFlow<()>, F::Error> {
    family.record(row)?;
    let now = family.now();
    Ok(observer.observe(&StepRecord {
        step: now.step,
        t: now.t,
        values: row,
    }))
}
