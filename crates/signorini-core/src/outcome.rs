//! What a finished run gives back: its summary, extra tables and figures ([`RunOutput`]), or why
//! it failed ([`RunError`]). A leaf: the job kinds build these, nothing here knows the job kinds.

use crate::band::BandError;
use crate::integrators::{RunStop, StepError};
use crate::soi2::Soi2Error;
use serde_json::{Map, Value};
use thiserror::Error;

/// A table an analysis produces besides the step records (e.g. `backbone`).
#[derive(Debug, Clone, PartialEq)]
pub struct Table {
    /// File stem, e.g. `backbone` for `backbone.csv`.
    pub name: String,
    /// Column names.
    pub columns: Vec<String>,
    /// Rows of values.
    pub rows: Vec<Vec<f64>>,
}

/// A picture a job produces (SVG text).
#[derive(Debug, Clone, PartialEq)]
pub struct Figure {
    /// File stem, e.g. `backbone` for `backbone.svg`.
    pub name: String,
    /// SVG document.
    pub svg: String,
}

/// What a finished run returns (the step records went to the observer).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RunOutput {
    /// `summary.json` (the caller adds `wall_s` and `steps_per_s`).
    pub summary: Map<String, Value>,
    /// Extra tables.
    pub tables: Vec<Table>,
    /// Figures.
    pub figures: Vec<Figure>,
}

/// Why a run failed.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum RunError {
    /// A step failed.
    #[error(transparent)]
    Step(#[from] StepError),
    /// The observer stopped the run (cancellation).
    #[error("stopped after {step} steps")]
    Stopped {
        /// Steps done.
        step: u64,
    },
    /// The scheme's iteration matrix could not be factorised (M, C, K passed validation, so this
    /// only happens when θh or h is extreme enough to lose definiteness to round-off).
    #[error("iteration matrix of the scheme is not positive definite: {0}")]
    IterationMatrix(BandError),
    /// A SOI2 run failed (Newton, singular matrix, inconsistent start).
    #[error(transparent)]
    Soi2(Soi2Error),
}

impl From<RunStop> for RunError {
    fn from(s: RunStop) -> Self {
        match s {
            RunStop::Step(e) => RunError::Step(e),
            RunStop::Stopped { step } => RunError::Stopped { step },
        }
    }
}

impl From<Soi2Error> for RunError {
    fn from(e: Soi2Error) -> Self {
        match e {
            Soi2Error::Stopped { step } => RunError::Stopped { step },
            other => RunError::Soi2(other),
        }
    }
}
