//! `[study]`: speed against error as a job. A base spec, schemes, a grid over spec fields, a
//! reference and an error norm; [`crate::study`] expands it into runs and reports on them.

use super::JobSpec;
use super::integrator::IntegratorSpec;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::collections::BTreeMap;

/// `[study]`: runs every scheme at every combination of the grid on the base spec, and reports
/// the error of each run against the reference with its CPU time (`study.csv`,
/// `work_precision.svg`) and the observed orders of convergence per scheme (`summary.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct StudySpec {
    /// The base spec: the path of a spec file (relative to the study's file; `signorini run`
    /// only) or the spec inline (`[study.base]`).
    pub base: StudyBase,
    /// `"exact"` (the scene's exact solution: `bouncing_ball`, `dep_bar`, `jay_negrut_test`) or a
    /// fine run `{ scheme = "...", h = ..., <scheme parameters> }` of the base model.
    pub reference: ReferenceSpec,
    /// The norm of the error over the recorded steps and quantities (default `max_abs`).
    #[serde(default)]
    pub error: ErrorNorm,
    /// The schemes compared, each an `[integrator]` table (`scheme = "..."` and its parameters).
    pub schemes: Vec<IntegratorSpec>,
    /// Spec field paths (`"time.h"`, `"model.restitution"`) and the values each takes; every
    /// combination is run with every scheme. Paths joined by commas vary together
    /// (`"model.elements,time.h" = [[100, 2e-3], [200, 1e-3]]`). The orders are observed
    /// along the axis that sets `time.h` (none without one).
    #[serde(default)]
    pub grid: BTreeMap<String, Vec<Value>>,
}

/// The base spec of a study.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(untagged)]
pub enum StudyBase {
    /// A spec file, relative to the study's file.
    File(String),
    /// The spec inline.
    Inline(Box<JobSpec>),
}

/// What the runs are compared with.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(untagged)]
pub enum ReferenceSpec {
    /// `"exact"`: the scene's exact solution.
    Exact(ExactReference),
    /// A fine run of the base model with this scheme and step size.
    Run(ReferenceRun),
}

/// `reference = "exact"`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ExactReference {
    /// The scene's exact solution.
    Exact,
}

/// `reference = { scheme = "...", h = ..., ... }`: a fine run of the base model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ReferenceRun {
    /// Step size of the reference run (> 0, normally much smaller than the grid's).
    pub h: f64,
    /// Its scheme and parameters.
    #[serde(flatten)]
    pub integrator: IntegratorSpec,
}

/// The norm of a run's error e_{k,i} = x_i(t_k) − x_i,ref(t_k) over its recorded steps k and
/// compared quantities i. Each quantity keeps its own unit: probes of a model in metres and
/// radians are compared as plain numbers, so `max_abs` is the largest error of any of them in
/// its own unit (probe quantities of one unit to read it in that unit).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ErrorNorm {
    /// max_{k,i} |e_{k,i}|.
    #[default]
    MaxAbs,
    /// √(mean_{k,i} e_{k,i}²).
    Rms,
    /// max_i |e_{K,i}| at the last recorded step K.
    Final,
    /// Σ_k |P_k − I_k| / Σ_k I_k: the relative L¹ error of the contact impulse per step, for
    /// `dep_bar` against its exact solution only (`reference = "exact"`): P_k is the run's
    /// `p_0`, its impulse over [t_{k−1}, t_k], and I_k = −∫ r dt the exact force's over the same
    /// step, integrated exactly (r is piecewise linear). Every step must be recorded
    /// (`output.every = 1`).
    ImpulseL1,
}

impl ErrorNorm {
    /// The name as written in specs.
    pub fn name(self) -> &'static str {
        match self {
            ErrorNorm::MaxAbs => "max_abs",
            ErrorNorm::Rms => "rms",
            ErrorNorm::Final => "final",
            ErrorNorm::ImpulseL1 => "impulse_l1",
        }
    }
}
