//! How a run reports its steps: a fixed list of column names, then one [`StepRecord`] per
//! recorded step handed to an [`Observer`].
//!
//! The core never knows where the records go: the service implements [`Observer`] with a zenoh
//! publisher and a store writer, the CLI with a CSV writer, the tests with a `Vec`.
//! Every output (steps.csv, the zenoh energy frames, `GET /v1/jobs/{id}/result`) uses the same
//! columns in the same order, so the values a subscriber receives are the stored ones, bit for bit.

use crate::checkpoint::Checkpoint;
use std::ops::ControlFlow;

/// Names of the values of every [`StepRecord`] of a run, fixed before the first step.
///
/// `step` and `t` are not part of the list: they are fields of the record and the first two
/// columns of every table.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Columns(Vec<String>);

impl Columns {
    /// Columns from names, in order.
    pub fn new(names: Vec<String>) -> Self {
        Self(names)
    }

    /// The names, in order.
    pub fn names(&self) -> &[String] {
        &self.0
    }

    /// Number of values per record.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// True when records carry no value besides `step` and `t`.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// Position of the column `name`, if the run has it.
    pub fn index(&self, name: &str) -> Option<usize> {
        self.0.iter().position(|c| c == name)
    }
}

/// One recorded step: its number, its time and the values of the run's [`Columns`].
#[derive(Debug, Clone, Copy)]
pub struct StepRecord<'a> {
    /// Step number; 0 is the initial state.
    pub step: u64,
    /// Time at the end of the step.
    pub t: f64,
    /// One value per column of the run, in column order.
    pub values: &'a [f64],
}

/// Progress of a run, reported at every step whether it is recorded or not.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Progress {
    /// Steps (or tasks, for analyses) done so far.
    pub done: u64,
    /// Steps (or tasks) the run will do in all.
    pub total: u64,
    /// Current time (0 for analyses that have no time).
    pub t: f64,
}

impl Progress {
    /// Fraction done, in [0, 1].
    pub fn fraction(&self) -> f64 {
        if self.total == 0 {
            1.0
        } else {
            (self.done as f64 / self.total as f64).min(1.0)
        }
    }
}

/// Receives what a run produces. Returning [`ControlFlow::Break`] from any method stops the run
/// at the end of the current step; the run then ends with [`crate::outcome::RunError::Stopped`].
pub trait Observer {
    /// Called once before the first record, with the run's columns.
    fn start(&mut self, columns: &Columns) {
        let _ = columns;
    }

    /// Called for each recorded step (every `output.every`-th step, and the last one).
    fn observe(&mut self, record: &StepRecord<'_>) -> ControlFlow<()>;

    /// Called after every step (recorded or not) and every analysis task: the place to check
    /// for cancellation and to report progress. Must be cheap.
    fn progress(&mut self, progress: Progress) -> ControlFlow<()> {
        let _ = progress;
        ControlFlow::Continue(())
    }

    /// Called after every step of a time integration, after [`Observer::progress`]: whether the
    /// run should hand a [`Checkpoint`] now (never, by default). The caller answers from its
    /// own clock or step count (`output.checkpoint_seconds`, `output.checkpoint_steps`). Must be
    /// cheap.
    fn checkpoint_due(&mut self, progress: Progress) -> bool {
        let _ = progress;
        false
    }

    /// Receives the run's checkpoint after a step for which [`Observer::checkpoint_due`] said
    /// yes; [`Checkpoint::encode`] makes it bytes, [`crate::job::resume`] continues from it.
    fn checkpoint(&mut self, checkpoint: &mut Checkpoint) {
        let _ = checkpoint;
    }
}

/// An observer that keeps every record in memory, column by column (tests, small jobs).
#[derive(Debug, Clone, Default)]
pub struct Recorder {
    /// Column names, as given by [`Observer::start`].
    pub columns: Columns,
    /// Step numbers of the records.
    pub steps: Vec<u64>,
    /// Times of the records.
    pub t: Vec<f64>,
    /// Values, one `Vec` per record.
    pub rows: Vec<Vec<f64>>,
}

impl Recorder {
    /// All recorded values of column `name`, or `None` when the run has no such column.
    pub fn column(&self, name: &str) -> Option<Vec<f64>> {
        let i = self.columns.index(name)?;
        Some(self.rows.iter().map(|r| r[i]).collect())
    }
}

impl Observer for Recorder {
    fn start(&mut self, columns: &Columns) {
        self.columns = columns.clone();
    }

    fn observe(&mut self, record: &StepRecord<'_>) -> ControlFlow<()> {
        self.steps.push(record.step);
        self.t.push(record.t);
        self.rows.push(record.values.to_vec());
        ControlFlow::Continue(())
    }
}
