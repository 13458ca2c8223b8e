//! The job spec: one set of serde types is the schema of the three spellings (TOML for the CLI,
//! JSON over HTTP, protobuf over gRPC converts to it). Field names are a public contract: add
//! fields freely, rename none. Unknown fields are rejected.
//!
//! A spec is only data; [`crate::job::Job::from_spec`] validates it once and builds the model and
//! the integrator, with errors that name the field ([`SpecError`]). The sections every kind of
//! job shares (`[time]`, `[contact_solver]`, `[output]`) are checked here, one function each.
//! This module tree imports no job, run or analysis code (only plain parameter types).

pub mod analysis;
pub mod check;
pub mod error;
pub mod integrator;
pub mod lagrangian;
pub mod model;
pub mod rigid;
pub mod study;
pub mod support;

pub use analysis::{AnalysisSpec, Excitation, ForcedResponseSpec, ModalSpec};
pub use error::SpecError;
pub use integrator::{
    AlphaCoefficientsSpec, HhtSoi2Spec, IndexSetSpec, IntegratorSpec, MoreauJeanSpec, NewtonSpec,
    NsAlphaSpec, NsHhtSpec, NsNewmarkSpec, PositionContactSpec, SchemeFamily,
    Soi2GeneralizedAlphaSpec, Soi2NewtonSpec, StartSpec, WfemSpec,
};
pub use lagrangian::{JointSpec, LagrangianSpec, MassSpec, Term, UserContactSpec};
pub use model::{HarmonicForceSpec, LinearSpec, ModelSpec};
pub use rigid::{RigidBodiesSpec, RigidBodySpec, ShapeSpec};

use crate::integrators::OutputOptions;
use crate::lcp::{LcpOptions, LcpSolverKind};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// A whole job.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct JobSpec {
    /// The JSON Schema this file follows (`signorini schema`), for editors; runs ignore it.
    #[serde(rename = "$schema", default, skip_serializing_if = "Option::is_none")]
    pub schema: Option<String>,
    /// Optional label.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// The model (required by time-integration jobs).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model: Option<ModelSpec>,
    /// The integrator; Moreau–Jean with θ = ½ when absent.
    #[serde(default)]
    pub integrator: IntegratorSpec,
    /// Step size and duration (required by time-integration jobs).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time: Option<TimeSpec>,
    /// LCP solver settings.
    #[serde(default)]
    pub contact_solver: ContactSolverSpec,
    /// What to record.
    #[serde(default)]
    pub output: OutputSpec,
    /// A job that is not a time integration (`kind = "nonsmooth_modes"` or `"forced_response"`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub analysis: Option<AnalysisSpec>,
    /// Bounds checked by `signorini check` (the CI gate); `run` and the service ignore them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub check: Option<check::CheckSpec>,
    /// A study: runs of the `base` spec over schemes and a grid, compared with a reference
    /// (`signorini run STUDY.toml`); the other sections then stay empty.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub study: Option<study::StudySpec>,
}

/// `[time]`: step size and duration (`t_end` or `steps`, not both).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TimeSpec {
    /// Step size h > 0.
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub h: f64,
    /// Final time ≥ 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 0.0))]
    pub t_end: Option<f64>,
    /// Number of steps.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub steps: Option<u64>,
    /// Relative step sizes repeated over the run (variable-step schemes only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pattern: Option<Vec<f64>>,
    /// Use the step-size adjusting formulas (variable-step schemes only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub adjust: Option<bool>,
}

fn default_tolerance() -> f64 {
    1e-12
}

fn default_max_iterations() -> usize {
    100_000
}

/// `[contact_solver]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ContactSolverSpec {
    /// `auto` (default), `lemke`, `pgs`, `enum` or `banded_active_set` (the impulse solved on
    /// the banded iteration matrix, memory and time linear in the dofs: linear models whose
    /// contacts are one dof each, no two on a dof, without friction; the α-family also needs a
    /// lumped mass). `auto` takes `banded_active_set` for such models from 201 contacts on, and
    /// otherwise enumeration up to 3 contacts in the index set, Lemke up to 200, PGS above. A
    /// step with friction (μ > 0 on a contact of the index set) solves the friction problem:
    /// `auto` runs the nonsmooth Gauss–Seidel (NSGS) first and Lemke on the LCP reformulation of
    /// the planar cone when NSGS does not converge; `lemke` and `pgs` run that one only.
    #[serde(default)]
    pub kind: LcpSolverKind,
    /// Largest complementarity error accepted, default 1e-12.
    #[serde(default = "default_tolerance")]
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub tolerance: f64,
    /// Pivot or sweep budget, default 100 000.
    #[serde(default = "default_max_iterations")]
    #[schemars(range(min = 1))]
    pub max_iterations: usize,
    /// `rigid_bodies` scenes only: the largest error of a step's 3D friction problem accepted
    /// when the solver spends its budget above `tolerance` (≥ `tolerance`). The step then goes
    /// on with the solver's iterate of smallest error, and the summary counts such steps
    /// (`friction_steps_accepted`) and their largest error (`friction_error_max`). Unset
    /// (default): such a step fails the run.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub accept_error: Option<f64>,
}

impl Default for ContactSolverSpec {
    fn default() -> Self {
        Self {
            kind: LcpSolverKind::Auto,
            tolerance: default_tolerance(),
            max_iterations: default_max_iterations(),
            accept_error: None,
        }
    }
}

fn one() -> u64 {
    1
}

/// `[output]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    /// Record every k-th step (≥ 1, default 1); the last step is always recorded.
    #[serde(default = "one")]
    #[schemars(range(min = 1))]
    pub every: u64,
    /// Dofs whose q_j, v_j are recorded (default none).
    #[serde(default)]
    pub probes: Vec<usize>,
    /// Wall-clock seconds between two checkpoints of a running time integration (`signorini run
    /// --out DIR` writes `DIR/checkpoint.bin`, the service its store); > 0, default 30. The
    /// caller measures the time: the numerical core keeps no clock.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub checkpoint_seconds: Option<f64>,
    /// Steps between two checkpoints, in addition to `checkpoint_seconds` (≥ 1, default none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 1))]
    pub checkpoint_steps: Option<u64>,
    /// `rigid_bodies` only: write the `contacts` table (`contacts.csv`): per recorded step k ≥ 1,
    /// one row per contact of the index set of that step (detected at t_{k−1}) with its bodies,
    /// point, normal, gap and impulse P_{k}. Default false.
    #[serde(default, skip_serializing_if = "is_false")]
    pub contacts: bool,
    /// `rigid_bodies` only: `signorini run` writes VTK XML files per recorded step that ParaView
    /// opens (`vtk/bodies.pvd`: the bodies' surfaces; `vtk/contacts.pvd`: the contact points with
    /// their impulses and forces). Implies the `contacts` table, which the contact files are
    /// made from. Default false.
    #[serde(default, skip_serializing_if = "is_false")]
    pub vtk: bool,
}

fn is_false(b: &bool) -> bool {
    !*b
}

impl Default for OutputSpec {
    fn default() -> Self {
        Self {
            every: 1,
            probes: Vec::new(),
            checkpoint_seconds: None,
            checkpoint_steps: None,
            contacts: false,
            vtk: false,
        }
    }
}

/// Default of `output.checkpoint_seconds`.
pub const CHECKPOINT_SECONDS: f64 = 30.0;

/// When a caller checkpoints a run: every `seconds` of wall time, and every `steps` steps if
/// given (`output.checkpoint_seconds`, `output.checkpoint_steps`, checked).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CheckpointPeriod {
    /// Seconds of wall time (> 0).
    pub seconds: f64,
    /// Steps (≥ 1), if given.
    pub steps: Option<u64>,
}

impl OutputSpec {
    /// The checkpoint period; errors name `output.checkpoint_seconds` / `output.checkpoint_steps`.
    pub fn checkpoint_period(&self) -> Result<CheckpointPeriod, SpecError> {
        let seconds = self.checkpoint_seconds.unwrap_or(CHECKPOINT_SECONDS);
        if !seconds.is_finite() || seconds <= 0.0 {
            return Err(SpecError::new(
                "output.checkpoint_seconds",
                format!("must be a finite number of seconds > 0, got {seconds}"),
            ));
        }
        if self.checkpoint_steps == Some(0) {
            return Err(SpecError::new("output.checkpoint_steps", "must be ≥ 1"));
        }
        Ok(CheckpointPeriod {
            seconds,
            steps: self.checkpoint_steps,
        })
    }
}

impl JobSpec {
    /// The `[time]` section, required by every time integration.
    pub fn time_section(&self) -> Result<&TimeSpec, SpecError> {
        self.time
            .as_ref()
            .ok_or_else(|| SpecError::new("time", "missing section"))
    }
}

/// Most steps a job may ask for: 2⁵³, beyond which the step times k·h are no longer exact in
/// f64 (the service has its own, much lower, configurable limit).
pub const MAX_STEPS: u64 = 1 << 53;

/// Where a run ends.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum End {
    /// At this time.
    Time(f64),
    /// After this many steps.
    Steps(u64),
}

/// A checked `[time]` section.
#[derive(Debug, Clone, PartialEq)]
pub struct Steps {
    /// Base step size h > 0.
    pub h: f64,
    /// Relative step sizes repeated over the run (each finite and > 0; `[1]` when not given).
    pub pattern: Vec<f64>,
    /// Where the run ends.
    pub end: End,
    /// Use the step-size adjusting formulas (default true; variable-step schemes only).
    pub adjust: bool,
}

impl Steps {
    /// The number of constant steps: `steps`, or `t_end / h` rounded to the nearest step when
    /// `t_end` is a multiple of h up to round-off, up otherwise.
    pub fn count(&self) -> u64 {
        match self.end {
            End::Steps(n) => n,
            End::Time(t) => {
                let ratio = t / self.h;
                let nearest = ratio.round();
                if (ratio - nearest).abs() <= 1e-9 * ratio.max(1.0) {
                    nearest as u64
                } else {
                    ratio.ceil() as u64
                }
            }
        }
    }
}

impl TimeSpec {
    /// Checks the section: h > 0; `t_end` ≥ 0 or `steps`, not both; h ≤ `t_end` when
    /// `t_end` > 0; at most [`MAX_STEPS`] steps
    /// (counted with the mean relative step); `pattern` and `adjust` only where the scheme takes
    /// variable steps: `fixed_step` is the refusal of variable steps by the scheme × feature
    /// table ([`support::refusal`] of [`support::Feature::VariableStep`]), `None` where they are
    /// taken. Errors name the field.
    pub fn steps(&self, fixed_step: Option<SpecError>) -> Result<Steps, SpecError> {
        if !(self.h.is_finite() && self.h > 0.0) {
            return Err(SpecError::new(
                "time.h",
                format!("must be a finite number > 0, got {}", self.h),
            ));
        }
        let variable_steps = fixed_step.is_none();
        if let Some(refusal) = fixed_step
            && self.pattern.is_some()
        {
            return Err(refusal);
        }
        if !variable_steps && self.adjust.is_some() {
            return Err(SpecError::new(
                "time.adjust",
                "the adjusting formulas belong to the SOI2 schemes only",
            ));
        }
        let pattern = self.pattern.clone().unwrap_or_else(|| vec![1.0]);
        if pattern.is_empty() {
            return Err(SpecError::new(
                "time.pattern",
                "must have at least one relative step size",
            ));
        }
        if let Some(p) = pattern.iter().find(|p| !(p.is_finite() && **p > 0.0)) {
            return Err(SpecError::new(
                "time.pattern",
                format!("relative step sizes must be finite and > 0, got {p}"),
            ));
        }
        let too_many = |field: &str, estimate: f64| {
            SpecError::new(
                field,
                format!(
                    "{estimate:.3e} steps: more than 2⁵³, where the step times k·h stop being exact"
                ),
            )
        };
        let end = match (self.t_end, self.steps) {
            (Some(_), Some(_)) => {
                return Err(SpecError::new(
                    "time.steps",
                    "give t_end or steps, not both",
                ));
            }
            (None, None) => {
                return Err(SpecError::new("time.t_end", "missing: give t_end or steps"));
            }
            (None, Some(n)) if n > MAX_STEPS => return Err(too_many("time.steps", n as f64)),
            (None, Some(n)) => End::Steps(n),
            (Some(t), None) => {
                if !(t.is_finite() && t >= 0.0) {
                    return Err(SpecError::new(
                        "time.t_end",
                        format!("must be a finite number ≥ 0, got {t}"),
                    ));
                }
                // One step longer than the whole run would integrate past t_end (h = 10 with
                // t_end = 5 ran to t = 10): refused rather than silently overshot.
                if t > 0.0 && self.h > t * (1.0 + 1e-9) {
                    return Err(SpecError::new(
                        "time.h",
                        format!(
                            "h = {} is longer than t_end = {t}: no step ends at t_end",
                            self.h
                        ),
                    ));
                }
                let mean = pattern.iter().sum::<f64>() / pattern.len() as f64;
                let estimate = t / (self.h * mean);
                if estimate > MAX_STEPS as f64 {
                    return Err(too_many("time.t_end", estimate));
                }
                End::Time(t)
            }
        };
        Ok(Steps {
            h: self.h,
            pattern,
            end,
            adjust: self.adjust.unwrap_or(true),
        })
    }
}

impl ContactSolverSpec {
    /// `accept_error`, checked: finite and ≥ `tolerance` (the job refuses it outside a
    /// `rigid_bodies` scene).
    pub fn accept_error(&self) -> Result<Option<f64>, SpecError> {
        match self.accept_error {
            Some(bound) if !(bound.is_finite() && bound >= self.tolerance) => Err(SpecError::new(
                "contact_solver.accept_error",
                format!(
                    "must be finite and ≥ contact_solver.tolerance ({}), got {bound}",
                    self.tolerance
                ),
            )),
            bound => Ok(bound),
        }
    }

    /// The checked LCP solver options (tolerance > 0, at least one iteration).
    pub fn options(&self) -> Result<LcpOptions, SpecError> {
        if !self.tolerance.is_finite() || self.tolerance <= 0.0 {
            return Err(SpecError::new(
                "contact_solver.tolerance",
                format!("must be > 0, got {}", self.tolerance),
            ));
        }
        if self.max_iterations == 0 {
            return Err(SpecError::new(
                "contact_solver.max_iterations",
                "must be ≥ 1",
            ));
        }
        Ok(LcpOptions {
            kind: self.kind,
            tolerance: self.tolerance,
            max_iterations: self.max_iterations,
        })
    }
}

/// Which probes a job can record: the dofs `0..n`, or none (and why not).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Probes {
    /// Dofs (or coordinates) `0..n`.
    Dofs(usize),
    /// None: the reason.
    Unsupported(&'static str),
}

impl OutputSpec {
    /// The checked output options: `every` ≥ 1, each probe a dof of the model.
    pub fn options(&self, probes: Probes) -> Result<OutputOptions, SpecError> {
        if self.every == 0 {
            return Err(SpecError::new("output.every", "must be ≥ 1"));
        }
        self.checkpoint_period()?;
        match probes {
            Probes::Unsupported(reason) if !self.probes.is_empty() => {
                return Err(SpecError::new("output.probes", reason));
            }
            Probes::Dofs(n) => {
                if let Some(&j) = self.probes.iter().find(|&&j| j >= n) {
                    return Err(SpecError::new(
                        "output.probes",
                        format!("dof {j} does not exist (the model has {n} dofs)"),
                    ));
                }
            }
            Probes::Unsupported(_) => {}
        }
        Ok(OutputOptions {
            every: self.every,
            probes: self.probes.clone(),
        })
    }
}

const SOI2_SCHEMES: &str = "soi2_generalized_alpha, soi2_hht or hht_i3";
const SOI2_SCENES: &str = "pendulum, slider_crank, jay_negrut_test or lagrangian";

/// The error for a scene and a scheme that do not go together (a linear scheme on a nonlinear
/// constrained scene, or a SOI2 scheme on a linear one).
pub fn mismatch(model: &ModelSpec, scheme: &str) -> SpecError {
    let scene = model.scene();
    if let ModelSpec::Lagrangian(_) = model {
        SpecError::new(
            "integrator.scheme",
            format!(
                "scene `lagrangian` runs with {SOI2_SCHEMES} (joints, no contacts), moreau_jean or ns_generalized_alpha (joints, contacts, both), got `{scheme}`"
            ),
        )
    } else if model.is_constrained() {
        SpecError::new(
            "integrator.scheme",
            format!(
                "scene `{scene}` is a nonlinear constrained model: it needs {SOI2_SCHEMES}, got `{scheme}`"
            ),
        )
    } else {
        SpecError::new(
            "integrator.scheme",
            format!(
                "scheme `{scheme}` integrates nonlinear constrained models ({SOI2_SCENES}), not scene `{scene}`"
            ),
        )
    }
}

/// The JSON Schema (draft 2020-12) of a job spec, generated from these types: each field's doc
/// comment is its `description`, its serde default its `default`, and the ranges the builders
/// check are `minimum`/`maximum` where they are closed bounds (stated in the description
/// otherwise). Editors validate and complete TOML and JSON spec files with it; the CLI prints
/// it (`signorini schema`) and [`crate::capabilities`] is read from it.
pub fn json_schema() -> serde_json::Value {
    schemars::schema_for!(JobSpec).to_value()
}
