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
/// The impacts of a step: the contacts whose impulse became positive after a step without
/// (`previous`, overwritten by `impulse` for the next step).
pub(crate) fn count_impacts(previous: &mut [f64], impulse: &[f64]) -> u64 {
    let mut impacts = 0;
    for (p_old, &p) in previous.iter_mut().zip(impulse) {
        impacts += u64::from(p > 0.0 && *p_old <= 0.0);
        *p_old = p;
    }
    impacts
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::observer::Recorder;
    use serde::Deserialize;
    use std::ops::ControlFlow;

    /// x_{k+1} = x_k / 2 from x_0 = 1 for `steps` steps: the smallest family.
    struct Halving {
        steps: u64,
        k: u64,
        x: f64,
    }

    #[derive(Serialize, Deserialize)]
    struct HalvingMemory {
        k: u64,
        x: f64,
    }

    impl TimeStepping for Halving {
        type Memory = HalvingMemory;
        type Error = CheckpointError;
        const RUN: RunKind = RunKind::Linear;
        fn columns(&self) -> Columns {
            Columns::new(vec!["x".to_string()])
        }
        fn total_steps(&self) -> u64 {
            self.steps
        }
        fn is_done(&mut self, k: u64) -> bool {
            k >= self.steps
        }
        fn step(&mut self, k: u64) -> Result<(), CheckpointError> {
            (self.k, self.x) = (k, 0.5 * self.x);
            Ok(())
        }
        fn now(&self) -> StepTime {
            StepTime {
                step: self.k,
                t: 0.25 * self.k as f64,
            }
        }
        fn record(&mut self, row: &mut Vec<f64>) -> Result<(), CheckpointError> {
            row.clear();
            row.push(self.x);
            Ok(())
        }
        fn memory(&self) -> HalvingMemory {
            HalvingMemory {
                k: self.k,
                x: self.x,
            }
        }
        fn restore(&mut self, m: HalvingMemory) -> Result<(), CheckpointError> {
            (self.k, self.x) = (m.k, m.x);
            Ok(())
        }
    }

    fn halving(steps: u64) -> Halving {
        Halving {
            steps,
            k: 0,
            x: 1.0,
        }
    }

    /// Records everything, hands a checkpoint after step `at`, stops after step `stop`.
    struct Cut {
        rec: Recorder,
        at: u64,
        stop: u64,
        kept: Option<Checkpoint>,
    }

    impl Observer for Cut {
        fn start(&mut self, columns: &Columns) {
            self.rec.start(columns);
        }
        fn observe(&mut self, record: &StepRecord<'_>) -> ControlFlow<()> {
            self.rec.observe(record)
        }
        fn progress(&mut self, p: Progress) -> ControlFlow<()> {
            if p.done >= self.stop {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        }
        fn checkpoint_due(&mut self, p: Progress) -> bool {
            p.done == self.at
        }
        fn checkpoint(&mut self, c: &mut Checkpoint) {
            self.kept = Some(c.clone());
        }
    }

    #[test]
    fn records_the_initial_state_every_kth_step_and_the_last() {
        let mut rec = Recorder::default();
        let stop = run(&mut halving(7), 3, &mut rec, None).unwrap();
        assert_eq!(stop, StopReason::Finished { steps: 7 });
        assert_eq!(rec.steps, [0, 3, 6, 7]);
        assert_eq!(rec.t, [0.0, 0.75, 1.5, 1.75]);
        assert_eq!(rec.column("x").unwrap(), [1.0, 0.125, 0.015625, 0.0078125]);
    }

    #[test]
    fn an_observer_stop_is_the_stop_reason_and_a_checkpoint_resumes_without_repeating_records() {
        let mut cut = Cut {
            rec: Recorder::default(),
            at: 4,
            stop: 5,
            kept: None,
        };
        let stop = run(&mut halving(9), 2, &mut cut, None).unwrap();
        assert_eq!(stop, StopReason::Observer { step: 5 });
        assert_eq!(cut.rec.steps, [0, 2, 4]);
        let checkpoint = cut.kept.expect("a checkpoint after step 4");
        assert_eq!(checkpoint.step(), 4);
        let mut rest = Recorder::default();
        let mut resumed = halving(9);
        let stop = run(&mut resumed, 2, &mut rest, Some(&checkpoint)).unwrap();
        assert_eq!(stop, StopReason::Finished { steps: 9 });
        assert_eq!(rest.steps, [6, 8, 9]);
        assert_eq!(
            rest.column("x").unwrap(),
            [0.015625, 0.00390625, 0.001953125]
        );
        // A checkpoint of another run is refused before any step.
        let foreign = Checkpoint::new(4, RunKind::Wave, &resumed.memory()).unwrap();
        let refused = run(&mut halving(9), 2, &mut Recorder::default(), Some(&foreign));
        assert!(
            matches!(refused, Err(CheckpointError::Mismatch(_))),
            "{refused:?}"
        );
    }
}
