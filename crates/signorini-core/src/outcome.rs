//! What a finished run gives back: its summary, extra tables and the data of its figures
//! ([`RunOutput`]), or why it failed ([`RunError`]). A leaf: the job kinds build these; nothing
//! here knows the job kinds.

use crate::band::BandError;
use crate::checkpoint::CheckpointError;
use crate::integrators::{LinearRunStats, RunStop, StepError};
use crate::lagrangian::projection::StartProjection;
use crate::nonlinear::generalized_alpha::NsAlphaSummary;
use crate::nonlinear::moreau_jean::{NonlinearRunStats, NonlinearRunStop, NonlinearStepError};
use crate::rigid::{DetectError, RigidRunError, RigidRunStats, RigidStepError};
use crate::soi2::{GlobalErrors, Soi2Error};
use serde::Serialize;
use serde_json::{Map, Value};
use std::time::Duration;
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

/// The data of a figure a job makes; the `signorini-figures` crate draws it. Each chart has a
/// name, the file stem of its figure ([`Chart::name`]).
#[derive(Debug, Clone, PartialEq)]
pub enum Chart {
    /// `energy` (energies and cumulative works), `residuals` (log₁₀ of the balance residual,
    /// the energy error and the constraint residuals), and for a user model `coordinates`,
    /// `gaps` and `impulses`, of a time integration: the min/max envelopes of its records.
    Trace(TraceChart),
    /// `backbone`: the admissible points of a nonsmooth-modes scan, every gap.
    Backbone(Vec<ModePoint>),
    /// `orbit_gap_*`: the displacement field of a periodic orbit over one period.
    SpaceTime(SpaceTime),
    /// `forced_response`: mean energies of a sweep over the backbone of the same bar.
    ForcedResponse(ForcedChart),
    /// `backbone_mode_K`: the frequency–energy plot of one nonsmooth mode over [ω_K, Ω_K].
    BackbonePanel(BackbonePanel),
    /// `contact_end`: u(L, t) and the contact force over one period of the shown orbits.
    ContactEnd(Vec<EndHistory>),
    /// `work_precision`: a study's error against CPU time, log–log, a curve per scheme.
    WorkPrecision(WorkPrecisionChart),
    /// `contact_region`: where a distributed obstacle is touched or pushes, against x and t.
    ContactRegion(ContactRegionChart),
}

impl Chart {
    /// File stem of the figure, e.g. `backbone` for `backbone.svg`.
    pub fn name(&self) -> &str {
        match self {
            Chart::Trace(t) => t.kind.name(),
            Chart::Backbone(_) => "backbone",
            Chart::SpaceTime(s) => &s.name,
            Chart::ForcedResponse(_) => "forced_response",
            Chart::BackbonePanel(b) => &b.name,
            Chart::ContactEnd(_) => "contact_end",
            Chart::WorkPrecision(_) => "work_precision",
            Chart::ContactRegion(_) => "contact_region",
        }
    }
}

/// The contact region of a distributed obstacle: a grid of cells (time bucket × group of
/// neighbouring contacts), each the strongest state seen in it: 0 free, 1 touching
/// (`gap ≤ delta`), 2 pushed (`P > 0`).
#[derive(Debug, Clone, PartialEq)]
pub struct ContactRegionChart {
    /// Abscissa of each group of contacts (increasing).
    pub x: Vec<f64>,
    /// Start time of each bucket.
    pub t: Vec<f64>,
    /// `states[bucket][group]`.
    pub states: Vec<Vec<u8>>,
    /// The touching threshold δ on the gap.
    pub delta: f64,
}

/// A study's work–precision diagram.
#[derive(Debug, Clone, PartialEq)]
pub struct WorkPrecisionChart {
    /// Title (names the reference and the norm).
    pub title: String,
    /// One curve per scheme (and values of the grid's other axes).
    pub curves: Vec<WorkPrecisionCurve>,
}

/// One curve of a [`WorkPrecisionChart`].
#[derive(Debug, Clone, PartialEq)]
pub struct WorkPrecisionCurve {
    /// Legend label.
    pub label: String,
    /// (CPU seconds, error) per run, by increasing CPU time.
    pub points: Vec<(f64, f64)>,
    /// The step size h of each point, in the order of `points`.
    pub h: Vec<f64>,
}

/// What a [`TraceChart`] shows (its figure's name).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TraceKind {
    /// `energy`: the energies and the cumulative works.
    Energy,
    /// `residuals`: log₁₀ of what must stay small (the balance residual, the energy error of a
    /// nonlinear scheme, the constraint residuals).
    Residuals,
    /// `coordinates`: the probed positions of a user model.
    Coordinates,
    /// `gaps`: the gaps of a user model's contacts.
    Gaps,
    /// `impulses`: the normal and tangential impulses of a user model's contacts.
    Impulses,
}

impl TraceKind {
    /// Every kind, in the order their charts come.
    pub const ALL: [TraceKind; 5] = [
        TraceKind::Energy,
        TraceKind::Residuals,
        TraceKind::Coordinates,
        TraceKind::Gaps,
        TraceKind::Impulses,
    ];

    /// The chart's name (file stem of its figure).
    pub fn name(self) -> &'static str {
        match self {
            TraceKind::Energy => "energy",
            TraceKind::Residuals => "residuals",
            TraceKind::Coordinates => "coordinates",
            TraceKind::Gaps => "gaps",
            TraceKind::Impulses => "impulses",
        }
    }

    /// Whether the chart's values are log₁₀|v| rather than v.
    pub fn is_log(self) -> bool {
        self == TraceKind::Residuals
    }
}

/// Envelopes of some columns of a run's records against t.
#[derive(Debug, Clone, PartialEq)]
pub struct TraceChart {
    /// What the chart shows (its values are log₁₀|v| for the residuals, v otherwise).
    pub kind: TraceKind,
    /// One series per traced column the run has, in a fixed order.
    pub series: Vec<TracedSeries>,
}

/// The envelope of one column: two points (t, value) per bucket, its extremes in time order;
/// a point that is not finite marks a bucket without a finite value (for a log series, a
/// bucket of exact zeros).
#[derive(Debug, Clone, PartialEq)]
pub struct TracedSeries {
    /// Column name in `steps.csv`.
    pub column: String,
    /// The envelope's points.
    pub points: Vec<(f64, f64)>,
}

/// A point of a frequency–energy backbone.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModePoint {
    /// Gap g0 of the scan.
    pub gap: f64,
    /// ω/ω₁.
    pub omega_over_omega1: f64,
    /// Energy / E_lin.
    pub energy_normalized: f64,
    /// k of the main branch the point lies on, if any.
    pub branch: Option<usize>,
}

/// The frequency–energy plot of the K-th nonsmooth mode (Figs. 5 and 6: K = 1, 2).
#[derive(Debug, Clone, PartialEq)]
pub struct BackbonePanel {
    /// Figure name, `backbone_mode_K`.
    pub name: String,
    /// K.
    pub mode: usize,
    /// The admissible points with ω in the panel's range, every gap.
    pub points: Vec<ModePoint>,
    /// Points to mark and label (the shown orbits, with their stability when run).
    pub marked: Vec<MarkedPoint>,
}

/// A labelled point of a backbone figure.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkedPoint {
    /// The point.
    pub point: ModePoint,
    /// Its label, e.g. `a: stable over 1000 T`.
    pub label: String,
}

/// One period of a shown orbit at the contact end (Fig. 8).
#[derive(Debug, Clone, PartialEq)]
pub struct EndHistory {
    /// Gap g0.
    pub gap: f64,
    /// Free-phase and contact-phase steps.
    pub m: usize,
    /// Contact-phase steps.
    pub p: usize,
    /// ω/ω₁.
    pub omega_over_omega1: f64,
    /// Energy / E_lin.
    pub energy_normalized: f64,
    /// Period T.
    pub period: f64,
    /// u(L, t_n), n = 0..=T/Δt.
    pub u: Vec<f64>,
    /// Contact force r(t_n) = S a_N (52) in contact, 0 in the free phases, n = 0..T/Δt.
    pub force: Vec<f64>,
}

/// Displacement u(x, t) of a periodic orbit over one period, sampled on a grid.
#[derive(Debug, Clone, PartialEq)]
pub struct SpaceTime {
    /// Figure name, `orbit_gap_positive`, `_zero` or `_negative`.
    pub name: String,
    /// Bar length L (x runs over [0, L]).
    pub length: f64,
    /// Period T (t runs over [0, T]).
    pub period: f64,
    /// Steps of the first free phase.
    pub free_steps: usize,
    /// Steps in contact per period.
    pub contact_steps: usize,
    /// Rows in increasing t, each the displacement at equally spaced x.
    pub field: Vec<Vec<f64>>,
}

/// A forced-response sweep and the backbone it is drawn over.
#[derive(Debug, Clone, PartialEq)]
pub struct ForcedChart {
    /// Driven by a moving wall (else by a distributed force).
    pub moving_wall: bool,
    /// E_lin, the energy unit.
    pub energy_linear_grazing: f64,
    /// The responses, sorted by damping then ω.
    pub responses: Vec<ForcedPoint>,
    /// Admissible backbone points of the same bar (empty when not asked for).
    pub backbone: Vec<ModePoint>,
}

/// The steady-state mean energy of one (γ, ω) run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForcedPoint {
    /// Damping γ.
    pub damping: f64,
    /// ω/ω₁.
    pub omega_over_omega1: f64,
    /// Mean cell energy.
    pub mean_energy: f64,
}

/// What a finished run returns (the step records went to the observer).
#[derive(Debug, Clone, PartialEq)]
pub struct RunOutput {
    /// `summary.json` (the caller attaches the wall time, [`RunSummary::with_timing`]).
    pub summary: RunSummary,
    /// Extra tables.
    pub tables: Vec<Table>,
    /// The data of its figures.
    pub charts: Vec<Chart>,
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
    /// A step of the nonlinear Moreau–Jean time-stepping failed (Newton, singular iteration
    /// matrix, a value that is not finite, the LCP), with its step and t.
    #[error(transparent)]
    Nonlinear(NonlinearStepError),
    /// A probe names a coordinate the model does not have.
    #[error("output.probes: coordinate {probe} does not exist (the model has {dofs})")]
    Probe {
        /// The probe.
        probe: usize,
        /// Coordinates of the model.
        dofs: usize,
    },
    /// The checkpoint to resume from was refused; nothing of it was restored.
    #[error(transparent)]
    Checkpoint(#[from] CheckpointError),
    /// A step of the rigid bodies' Moreau–Jean failed (detection, friction problem, Newton),
    /// with its step and t.
    #[error(transparent)]
    Rigid(RigidStepError),
    /// A `rigid_bodies` job was run without a contact detector
    /// ([`crate::job::run_with_detectors`] gives one).
    #[error("a rigid_bodies job needs a contact detector: run it with job::run_with_detectors")]
    NoDetector,
    /// The detector could not be built for the bodies (a degenerate convex hull).
    #[error("contact detector: {0}")]
    Detector(DetectError),
}

impl From<RigidRunError> for RunError {
    fn from(e: RigidRunError) -> Self {
        match e {
            RigidRunError::Step(e) => RunError::Rigid(e),
            RigidRunError::Checkpoint(e) => RunError::Checkpoint(e),
        }
    }
}

impl From<NonlinearRunStop> for RunError {
    fn from(s: NonlinearRunStop) -> Self {
        match s {
            NonlinearRunStop::Step(e) => RunError::Nonlinear(e),
            NonlinearRunStop::Stopped { step } => RunError::Stopped { step },
            NonlinearRunStop::Probe { probe, dofs } => RunError::Probe { probe, dofs },
            NonlinearRunStop::Checkpoint(e) => RunError::Checkpoint(e),
        }
    }
}

impl From<RunStop> for RunError {
    fn from(s: RunStop) -> Self {
        match s {
            RunStop::Step(e) => RunError::Step(e),
            RunStop::Stopped { step } => RunError::Stopped { step },
            RunStop::Checkpoint(e) => RunError::Checkpoint(e),
        }
    }
}

impl From<Soi2Error> for RunError {
    fn from(e: Soi2Error) -> Self {
        match e {
            Soi2Error::Stopped { step } => RunError::Stopped { step },
            Soi2Error::Checkpoint(e) => RunError::Checkpoint(e),
            other => RunError::Soi2(other),
        }
    }
}

/// `summary.json`: which job ran ([`SummaryHeader`]), what it measured ([`SummaryBody`], one
/// struct per job kind) and, once the caller attached it, how long it took ([`Timing`]). It
/// serialises flat, in that order: `name`, `scene`, `scheme` (or `analysis`), `kind`, the kind's fields, `wall_s`,
/// `steps_per_s`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunSummary {
    /// Name, scene, scheme or analysis.
    #[serde(flatten)]
    pub header: SummaryHeader,
    /// What the run measured.
    #[serde(flatten)]
    pub body: SummaryBody,
    /// Wall time, attached by the caller after the run.
    #[serde(flatten)]
    pub timing: Option<Timing>,
    /// How a `lagrangian` model's q0 and v0 were moved onto its joints
    /// (`model.project_onto_joints`); absent when they were taken as given.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub start_projection: Option<StartProjection>,
}

impl RunSummary {
    /// The summary of a run, without timing.
    pub fn new(header: SummaryHeader, body: SummaryBody) -> Self {
        Self {
            header,
            body,
            timing: None,
            start_projection: None,
        }
    }

    /// Attaches the wall time of the run: `wall_s`, and `steps_per_s` (steps per second of a
    /// time integration, 0 for an analysis or a zero wall time).
    pub fn with_timing(mut self, wall: Duration) -> Self {
        let wall_s = wall.as_secs_f64();
        let steps = self.body.steps().unwrap_or(0) as f64;
        self.timing = Some(Timing {
            wall_s,
            steps_per_s: if wall_s > 0.0 { steps / wall_s } else { 0.0 },
        });
        self
    }

    /// The summary as a JSON object (the `summary.json` document).
    pub fn to_map(&self) -> Map<String, Value> {
        match serde_json::to_value(self) {
            Ok(Value::Object(map)) => map,
            // A struct of numbers, strings and lists serialises to an object.
            _ => Map::new(),
        }
    }
}

/// The spec's identification of the job.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SummaryHeader {
    /// The spec's `name`, if any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// The scene of `[model]` (none for an `[analysis]`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scene: Option<String>,
    /// The integrator scheme of a time integration (none for an `[analysis]`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scheme: Option<String>,
    /// The analysis of an `[analysis]` job, e.g. `nonsmooth_modes` (none for a time integration).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub analysis: Option<String>,
}

/// Wall time of a run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Timing {
    /// Seconds from start to end of the run.
    pub wall_s: f64,
    /// Steps per second (0 for an analysis).
    pub steps_per_s: f64,
}

/// What a run measured, per job kind; `kind` is `time_integration` for the three integrating
/// kinds.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum SummaryBody {
    /// A linear model under a linear scheme.
    #[serde(rename = "time_integration")]
    Linear(LinearSummary),
    /// A constrained mechanism under a SOI2 scheme.
    #[serde(rename = "time_integration")]
    Soi2(Box<Soi2Summary>),
    /// A bar under WFEM.
    #[serde(rename = "time_integration")]
    Wave(WaveSummary),
    /// A nonlinear Lagrangian model with contacts under the nonlinear Moreau–Jean scheme.
    #[serde(rename = "time_integration")]
    Nonlinear(NonlinearSummary),
    /// A nonlinear Lagrangian model with joints and contacts under the nonsmooth
    /// generalized-α scheme.
    #[serde(rename = "time_integration")]
    NsAlpha(Box<NsAlphaSummary>),
    /// Rigid bodies under Moreau–Jean.
    #[serde(rename = "time_integration")]
    Rigid(RigidSummary),
    /// Backbones of the nonsmooth modes.
    NonsmoothModes(ModesSummary),
    /// A forced-response sweep.
    ForcedResponse(ForcedSummary),
}

impl SummaryBody {
    /// Steps integrated (none for an analysis).
    pub fn steps(&self) -> Option<u64> {
        match self {
            SummaryBody::Linear(s) => Some(s.stats.steps),
            SummaryBody::Soi2(s) => Some(s.steps),
            SummaryBody::Wave(s) => Some(s.stats.steps),
            SummaryBody::Nonlinear(s) => Some(s.stats.steps),
            SummaryBody::NsAlpha(s) => Some(s.stats.base.steps),
            SummaryBody::Rigid(s) => Some(s.stats.steps),
            SummaryBody::NonsmoothModes(_) | SummaryBody::ForcedResponse(_) => None,
        }
    }
}

/// Summary of a rigid-bodies run: the bodies and the step, then what the run measured
/// ([`RigidRunStats`], its fields flat).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RigidSummary {
    /// Bodies (fixed ones included).
    pub bodies: usize,
    /// Step size.
    pub h: f64,
    /// Steps, energies, the largest energy error, contacts, penetration, works, solver figures.
    #[serde(flatten)]
    pub stats: RigidRunStats,
}

/// Summary of a nonlinear Moreau–Jean run: the model's size and step, then what the run
/// measured ([`NonlinearRunStats`], its fields flat).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NonlinearSummary {
    /// Generalized coordinates.
    pub dofs: usize,
    /// Contacts.
    pub contacts: usize,
    /// Step size.
    pub h: f64,
    /// Steps, energies, the largest energy error, impacts, LCP and Newton figures, works.
    #[serde(flatten)]
    pub stats: NonlinearRunStats,
}

/// Summary of a linear-scheme run: the model's size and step, then what the run measured
/// ([`LinearRunStats`], its fields flat).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LinearSummary {
    /// Degrees of freedom.
    pub dofs: usize,
    /// Contacts.
    pub contacts: usize,
    /// Step size.
    pub h: f64,
    /// Steps, energies, the largest balance residual, impacts, LCP figures, works.
    #[serde(flatten)]
    pub stats: LinearRunStats,
}

/// Summary of a SOI2 run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Soi2Summary {
    /// Coordinates y.
    pub dofs: usize,
    /// Holonomic constraints (multipliers λ).
    pub holonomic_constraints: usize,
    /// Nonholonomic constraints (multipliers ψ).
    pub nonholonomic_constraints: usize,
    /// Base step h.
    pub h: f64,
    /// Relative step sizes, repeated.
    pub pattern: Vec<f64>,
    /// Whether the (14a)–(14b) adjustments were applied.
    pub adjust: bool,
    /// α_m.
    pub alpha_m: f64,
    /// α_f.
    pub alpha_f: f64,
    /// β.
    pub beta: f64,
    /// γ.
    pub gamma: f64,
    /// Formulation of the method.
    pub formulation: String,
    /// Steps done.
    pub steps: u64,
    /// Final time.
    pub t_end: f64,
    /// Sum of Newton iterations.
    pub newton_iterations_total: u64,
    /// Mean Newton iterations per step.
    pub newton_iterations_mean: f64,
    /// Largest Newton iteration count of a step.
    pub newton_iterations_max: usize,
    /// Newton strategy (`simplified` or `full`).
    pub newton: String,
    /// Newton Jacobians built.
    pub newton_jacobians_total: u64,
    /// max ‖g‖∞ over the steps.
    pub max_position_residual: f64,
    /// max ‖g_t + g_y z‖∞ over the steps.
    pub max_velocity_residual: f64,
    /// max ‖k‖∞ over the steps.
    pub max_nonholonomic_residual: f64,
    /// Mechanical energy at t₀.
    pub energy_initial: f64,
    /// Mechanical energy at the end.
    pub energy_final: f64,
    /// Work of the damping forces.
    pub work_damping_total: f64,
    /// Final positions.
    pub y_final: Vec<f64>,
    /// Final velocities.
    pub z_final: Vec<f64>,
    /// Final multipliers.
    pub lambda_final: Vec<f64>,
    /// Global errors against the exact solution, for models that have one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub errors: Option<GlobalErrors>,
    /// Steps whose constraint Jacobian had lost rank (singular positions, redundant joints;
    /// docs/soi2.md), solved with minimum-norm multipliers.
    pub rank_deficient_steps: u64,
    /// The smallest numerical rank of the constraint Jacobian on those steps (absent when none).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub smallest_rank: Option<usize>,
    /// Attempts rejected for a Newton failure and retried with h/2 (variable-step runs).
    pub rejected_steps: u64,
    /// Steps accepted on Newton's residual test with the constraint Jacobian at full numerical
    /// rank (next to a singular position; docs/soi2.md).
    pub near_singular_steps: u64,
}

/// Summary of a WFEM run: the bar's size and step, then what the run measured
/// ([`WaveRunStats`], its fields flat).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WaveSummary {
    /// Cells.
    pub cells: usize,
    /// Degrees of freedom (2 per cell).
    pub dofs: usize,
    /// Contacts (the bar's end).
    pub contacts: usize,
    /// Step size.
    pub h: f64,
    /// Steps, energies, the largest balance residual, works, closures, steps in contact.
    #[serde(flatten)]
    pub stats: WaveRunStats,
}

/// What a WFEM run measured over all its steps; its fields are those of `summary.json`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, serde::Deserialize)]
pub struct WaveRunStats {
    /// Steps done.
    pub steps: u64,
    /// Final time.
    pub t_end: f64,
    /// Cell energy at t = 0.
    pub energy_initial: f64,
    /// Cell energy at the end.
    pub energy_final: f64,
    /// max |balance_residual| over the records.
    pub max_abs_balance_residual: f64,
    /// Cumulative works.
    pub work_ext_total: f64,
    /// See `work_ext_total`.
    pub work_damping_total: f64,
    /// See `work_ext_total`.
    pub work_contact_total: f64,
    /// Number of gap closures (free → contact switches).
    pub closures: u64,
    /// Steps spent in contact.
    pub contact_steps: u64,
}

/// Summary of a nonsmooth-modes analysis.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModesSummary {
    /// Cells.
    pub cells: usize,
    /// Contact phases per period.
    pub phases: usize,
    /// Period range scanned, in steps.
    pub period_steps: [usize; 2],
    /// Per gap: points found.
    pub gaps: Vec<GapScan>,
    /// Rows of `backbone.csv`.
    pub points: usize,
    /// The stability run of the first-mode orbit (`null` when none ran).
    pub stability: Option<StabilityRun>,
}

/// The scan of one gap.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GapScan {
    /// Gap g0.
    pub gap: f64,
    /// Admissible orbits.
    pub admissible: usize,
    /// Candidates with a nontrivial kernel (admissible ones only unless `all_candidates`).
    pub candidates: usize,
}

/// The stability run of an orbit: its start perturbed, run for some periods.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StabilityRun {
    /// Gap g0.
    pub gap: f64,
    /// Free-phase steps of the orbit.
    pub m: usize,
    /// Contact-phase steps of the orbit.
    pub p: usize,
    /// Periods run.
    pub periods: usize,
    /// Relative size of the initial perturbation.
    pub perturbation: f64,
    /// Orbital distance of the perturbed run over its last period, relative to the orbit's size.
    pub relative_deviation: f64,
    /// Same measure for the unperturbed run (drift of the orbit itself).
    pub orbit_drift: f64,
}

/// Summary of a forced-response sweep.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ForcedSummary {
    /// Cells.
    pub cells: usize,
    /// Gap g0.
    pub gap: f64,
    /// `wall` or `force`.
    pub excitation: String,
    /// w0 or f0.
    pub amplitude: f64,
    /// (ω, γ) runs.
    pub tasks: u64,
    /// Largest relative balance residual of the runs.
    pub max_relative_balance_residual: f64,
    /// E_lin, the energy of the grazing first linear mode.
    pub energy_linear_grazing: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `summary.json` is flat, in the order header, `kind`, the kind's fields, timing; an
    /// absent name or scene is left out, a missing stability run is `null`.
    #[test]
    fn summary_serialises_flat_in_order() {
        let summary = RunSummary::new(
            SummaryHeader {
                name: None,
                scene: None,
                scheme: Some("moreau_jean".into()),
                analysis: None,
            },
            SummaryBody::NonsmoothModes(ModesSummary {
                cells: 4,
                phases: 1,
                period_steps: [2, 16],
                gaps: vec![GapScan {
                    gap: 0.0,
                    admissible: 3,
                    candidates: 5,
                }],
                points: 3,
                stability: None,
            }),
        )
        .with_timing(Duration::from_millis(500));
        assert_eq!(
            serde_json::to_string(&summary).ok().as_deref(),
            Some(
                r#"{"scheme":"moreau_jean","kind":"nonsmooth_modes","cells":4,"phases":1,"period_steps":[2,16],"gaps":[{"gap":0.0,"admissible":3,"candidates":5}],"points":3,"stability":null,"wall_s":0.5,"steps_per_s":0.0}"#
            )
        );
    }
}
