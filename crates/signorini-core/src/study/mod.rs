//! Studies: speed against error as a job (`[study]`, [`crate::spec::study`]).
//!
//! [`Study::from_spec`] expands a study into its runs — every scheme at every combination of
//! the grid, each a validated [`Job`] — and its reference (the scene's exact solution, or a
//! fine run). The caller runs them with a [`Samples`] observer each and measures their CPU time
//! (the core has no clock); [`Study::error`] compares a run with the reference in the study's
//! norm, and [`StudyReport`] gathers the points, fits the observed orders and makes the table,
//! the work–precision chart and the summary.

mod report;

pub use report::{ObservedOrder, StudyPoint, StudyReport, StudySummary};

use crate::job::Job;
use crate::observer::{Columns, Observer, StepRecord};
use crate::scenes::{Bar, BarSpec, BouncingBall};
use crate::soi2::ConstrainedModel;
use crate::soi2::models::JayNegrutTest;
use crate::spec::study::{ErrorNorm, ReferenceSpec, StudyBase, StudySpec};
use crate::spec::{JobSpec, ModelSpec, SpecError};
use crate::wfem::exact::{ExactBar, ExactSolution};
use serde_json::Value;
use std::ops::ControlFlow;

/// One run of a study.
#[derive(Debug, Clone)]
pub struct StudyRun {
    /// Which of `study.schemes`.
    pub scheme_index: usize,
    /// The scheme's label (`moreau_jean (theta=0.5)`).
    pub label: String,
    /// The value of each grid axis ([`Study::axes`]), in order.
    pub values: Vec<Value>,
    /// The run's step size.
    pub h: f64,
    /// The validated job.
    pub job: Job,
}

/// What the runs are compared with.
#[derive(Debug, Clone)]
pub enum Reference {
    /// The bouncing ball's exact motion, compared on `gap_0` (the height).
    Ball(BouncingBall),
    /// The Doyen–Ern–Piperno bar's exact solution by characteristics, compared on `gap_0`
    /// (g0 − u(L, t)).
    DepBar {
        /// The initial gap g0.
        gap: f64,
        /// The cross-section area (the exact force r is a stress: the impulse is −A ∫ r dt).
        area: f64,
        /// u(L, t).
        solution: Box<ExactSolution>,
    },
    /// The Jay–Negrut test problem (15), compared on the probed `y_j`.
    JayNegrut {
        /// The probed coordinates.
        probes: Vec<usize>,
    },
    /// A fine run, compared on every `q_j`, `y_j` and `gap_i` column both record (and a rigid
    /// body's position `NAME_x`, `NAME_y`, `NAME_z`).
    Run(Box<Job>),
}

impl Reference {
    /// `exact (bouncing_ball)` or `moreau_jean (theta=0.5), h = 1e-5`.
    pub fn describe(&self, spec: &ReferenceSpec) -> String {
        match (self, spec) {
            (Reference::Ball(_), _) => "exact (bouncing_ball)".into(),
            (Reference::DepBar { .. }, _) => "exact (dep_bar, by characteristics)".into(),
            (Reference::JayNegrut { .. }, _) => "exact (jay_negrut_test)".into(),
            (Reference::Run(_), ReferenceSpec::Run(r)) => {
                format!("{}, h = {:e}", scheme_label(&r.integrator), r.h)
            }
            (Reference::Run(_), _) => "a fine run".into(),
        }
    }
}

/// A study expanded into runs.
#[derive(Debug, Clone)]
pub struct Study {
    /// The study's spec.
    pub spec: StudySpec,
    /// The base spec's name.
    pub name: Option<String>,
    /// The base model's scene.
    pub scene: String,
    /// The grid's field paths, in order.
    pub axes: Vec<String>,
    /// Every run: schemes outer, grid combinations inner.
    pub runs: Vec<StudyRun>,
    /// The reference.
    pub reference: Reference,
}

/// The label of a scheme: its name and the parameters that differ from the scheme's defaults.
pub fn scheme_label(integrator: &crate::spec::IntegratorSpec) -> String {
    let name = integrator.scheme();
    let defaults = serde_json::from_value::<crate::spec::IntegratorSpec>(
        serde_json::json!({ "scheme": name }),
    )
    .ok()
    .and_then(|d| serde_json::to_value(d).ok());
    let default_of = |k: &str| defaults.as_ref().and_then(|d| d.get(k));
    match serde_json::to_value(integrator) {
        Ok(Value::Object(map)) => {
            let params: Vec<String> = map
                .iter()
                .filter(|(k, v)| {
                    k.as_str() != "scheme" && !v.is_null() && default_of(k) != Some(*v)
                })
                .map(|(k, v)| format!("{k}={v}"))
                .collect();
            if params.is_empty() {
                name.to_string()
            } else {
                format!("{name} ({})", params.join(", "))
            }
        }
        _ => name.to_string(),
    }
}

/// Sets the field at the dotted `path` of a spec written as JSON, creating the tables on the way.
fn set_path(spec: &mut Value, path: &str, value: Value) -> Result<(), String> {
    let mut node = spec;
    let parts: Vec<&str> = path.split('.').collect();
    if parts.iter().any(|p| p.is_empty()) {
        return Err("a field path is dot-separated names, e.g. time.h".into());
    }
    let (last, tables) = parts.split_last().ok_or("empty field path")?;
    for part in tables {
        let Value::Object(map) = node else {
            return Err(format!("'{part}' is inside a value that is not a table"));
        };
        node = map
            .entry(part.to_string())
            .or_insert_with(|| Value::Object(Default::default()));
    }
    match node {
        Value::Object(map) => {
            map.insert(last.to_string(), value);
            Ok(())
        }
        _ => Err(format!("'{last}' is inside a value that is not a table")),
    }
}

/// The (path, value) pairs of one grid axis: `"time.h" = 1e-3` sets one field;
/// `"model.elements,time.h" = [100, 1e-3]` sets several together (paths joined by commas, the
/// value an array of as many entries).
fn axis_assignments<'a>(axis: &'a str, value: &Value) -> Result<Vec<(&'a str, Value)>, SpecError> {
    let paths: Vec<&str> = axis.split(',').map(str::trim).collect();
    if paths.len() == 1 {
        return Ok(vec![(paths[0], value.clone())]);
    }
    match value {
        Value::Array(values) if values.len() == paths.len() => {
            Ok(paths.into_iter().zip(values.iter().cloned()).collect())
        }
        other => Err(SpecError::new(
            format!("study.grid.\"{axis}\""),
            format!(
                "each value sets {} fields together: an array of {} entries, got {other}",
                paths.len(),
                paths.len()
            ),
        )),
    }
}

/// Whether a grid axis sets `time.h` (alone or with other fields).
pub fn is_step_axis(axis: &str) -> bool {
    axis.split(',').any(|p| p.trim() == "time.h")
}

/// Every combination of the axes' values, the last axis fastest.
fn combinations(values: &[&Vec<Value>]) -> Vec<Vec<Value>> {
    values.iter().fold(vec![Vec::new()], |acc, axis| {
        acc.iter()
            .flat_map(|prefix| {
                axis.iter().map(move |v| {
                    let mut c = prefix.clone();
                    c.push(v.clone());
                    c
                })
            })
            .collect()
    })
}

impl Study {
    /// Expands `spec` on `base` (the base spec, already read when `study.base` is a file) into
    /// validated runs and a reference. Every error names the field: `study.schemes[1]`,
    /// `study.grid."time.h"[2]: model.restitution: …`, `study.reference`.
    pub fn from_spec(spec: &StudySpec, base: &JobSpec) -> Result<Study, SpecError> {
        if base.study.is_some() {
            return Err(SpecError::new(
                "study.base",
                "a study's base cannot be a study",
            ));
        }
        if base.analysis.is_some() {
            return Err(SpecError::new(
                "study.base",
                "a study compares time integrations; the base is an [analysis]",
            ));
        }
        let model = base
            .model
            .as_ref()
            .ok_or_else(|| SpecError::new("study.base.model", "missing section"))?;
        if spec.schemes.is_empty() {
            return Err(SpecError::new("study.schemes", "give at least one scheme"));
        }
        let axes: Vec<String> = spec.grid.keys().cloned().collect();
        for (path, values) in &spec.grid {
            if values.is_empty() {
                return Err(SpecError::new(
                    format!("study.grid.\"{path}\""),
                    "no values",
                ));
            }
        }
        let base_json =
            serde_json::to_value(base).map_err(|e| SpecError::new("study.base", e.to_string()))?;
        let child = |integrator: &crate::spec::IntegratorSpec,
                     assignments: &[(&str, Value)],
                     field: &str|
         -> Result<Job, SpecError> {
            let mut json = base_json.clone();
            let scheme = serde_json::to_value(integrator)
                .map_err(|e| SpecError::new(field, e.to_string()))?;
            set_path(&mut json, "integrator", scheme).map_err(|e| SpecError::new(field, e))?;
            for (axis, value) in assignments {
                for (path, v) in axis_assignments(axis, value)? {
                    set_path(&mut json, path, v)
                        .map_err(|e| SpecError::new(format!("study.grid.\"{axis}\""), e))?;
                }
            }
            let spec: JobSpec =
                serde_json::from_value(json).map_err(|e| SpecError::new(field, e.to_string()))?;
            Job::from_spec(&spec)
                .map_err(|e| SpecError::new(format!("{field}: {}", e.field), e.reason))
        };
        let value_lists: Vec<&Vec<Value>> = spec.grid.values().collect();
        let combos = combinations(&value_lists);
        let mut runs = Vec::with_capacity(spec.schemes.len() * combos.len());
        for (s, integrator) in spec.schemes.iter().enumerate() {
            for combo in &combos {
                let assignments: Vec<(&str, Value)> = axes
                    .iter()
                    .map(String::as_str)
                    .zip(combo.iter().cloned())
                    .collect();
                let field = if axes.is_empty() {
                    format!("study.schemes[{s}]")
                } else {
                    let at: Vec<String> = assignments
                        .iter()
                        .map(|(p, v)| format!("{p}={v}"))
                        .collect();
                    format!("study.schemes[{s}] at {}", at.join(", "))
                };
                let job = child(integrator, &assignments, &field)?;
                let h = job.spec().time.as_ref().map_or(f64::NAN, |t| t.h);
                runs.push(StudyRun {
                    scheme_index: s,
                    label: scheme_label(integrator),
                    values: combo.clone(),
                    h,
                    job,
                });
            }
        }
        let t_end = runs
            .iter()
            .filter_map(|r| r.job.spec().time.as_ref())
            .map(|t| t.t_end.unwrap_or(t.h * t.steps.unwrap_or(0) as f64))
            .fold(0.0f64, f64::max);
        let reference = match &spec.reference {
            ReferenceSpec::Exact(_) => exact_reference(model, base, t_end)?,
            ReferenceSpec::Run(r) => {
                if !(r.h.is_finite() && r.h > 0.0) {
                    return Err(SpecError::new(
                        "study.reference.h",
                        format!("must be > 0, got {}", r.h),
                    ));
                }
                let mut assignments = vec![("time.h", Value::from(r.h))];
                // The reference covers the longest run.
                if base.time.as_ref().is_some_and(|t| t.steps.is_some()) {
                    assignments.push(("time.steps", Value::Null));
                    assignments.push(("time.t_end", Value::from(t_end)));
                }
                Reference::Run(Box::new(child(
                    &r.integrator,
                    &assignments,
                    "study.reference",
                )?))
            }
        };
        if spec.error == ErrorNorm::ImpulseL1 && !matches!(reference, Reference::DepBar { .. }) {
            return Err(SpecError::new(
                "study.error",
                "impulse_l1 is the contact impulse error of dep_bar against its exact solution \
                 (reference = \"exact\" on scene dep_bar)",
            ));
        }
        Ok(Study {
            spec: spec.clone(),
            name: base.name.clone(),
            scene: model.scene().to_string(),
            axes,
            runs,
            reference,
        })
    }

    /// The error of a run's samples against the reference (`reference_samples` of the fine
    /// run when the reference is one), in the study's norm.
    pub fn error(&self, run: &Samples, reference: Option<&Samples>) -> Result<f64, SpecError> {
        if let (ErrorNorm::ImpulseL1, Reference::DepBar { solution, area, .. }) =
            (self.spec.error, &self.reference)
        {
            return impulse_error(run, solution, *area);
        }
        let mut acc = NormAccumulator::new(self.spec.error);
        match &self.reference {
            Reference::Run(_) => {
                let reference = reference.ok_or_else(|| {
                    SpecError::new("study.reference", "the reference run's samples are missing")
                })?;
                let pairs: Vec<(usize, usize)> = run
                    .names
                    .iter()
                    .enumerate()
                    .filter_map(|(i, n)| {
                        reference.names.iter().position(|m| m == n).map(|j| (i, j))
                    })
                    .collect();
                if pairs.is_empty() {
                    return Err(SpecError::new(
                        "study.reference",
                        "the reference run records none of the runs' q_j, y_j, gap_i or body position columns",
                    ));
                }
                for (k, &t) in run.t.iter().enumerate() {
                    for &(i, j) in &pairs {
                        acc.add(k, run.values[k][i] - reference.at(t, j));
                    }
                }
            }
            exact => {
                let names = exact.compared_columns();
                let idx: Vec<usize> = names
                    .iter()
                    .map(|n| {
                        run.names.iter().position(|m| m == n).ok_or_else(|| {
                            SpecError::new(
                                "study.reference",
                                format!("the runs record no column {n} to compare with the exact solution (output.probes)"),
                            )
                        })
                    })
                    .collect::<Result<_, _>>()?;
                for (k, &t) in run.t.iter().enumerate() {
                    let x = exact.exact_values(t);
                    for (q, &i) in idx.iter().enumerate() {
                        acc.add(k, run.values[k][i] - x[q]);
                    }
                }
            }
        }
        Ok(acc.finish())
    }
}

impl Reference {
    /// The columns an exact reference is compared on.
    fn compared_columns(&self) -> Vec<String> {
        match self {
            Reference::Ball(_) | Reference::DepBar { .. } => vec!["gap_0".into()],
            Reference::JayNegrut { probes } => probes.iter().map(|j| format!("y_{j}")).collect(),
            Reference::Run(_) => Vec::new(),
        }
    }

    /// The exact values of [`Reference::compared_columns`] at t.
    fn exact_values(&self, t: f64) -> Vec<f64> {
        match self {
            Reference::Ball(ball) => vec![ball.exact_motion(t).0],
            Reference::DepBar { gap, solution, .. } => {
                vec![gap - solution.end_displacement(t)]
            }
            Reference::JayNegrut { probes } => {
                let y = JayNegrutTest::default()
                    .exact(t)
                    .map(|e| e.y)
                    .unwrap_or_default();
                probes
                    .iter()
                    .map(|&j| y.get(j).copied().unwrap_or(f64::NAN))
                    .collect()
            }
            Reference::Run(_) => Vec::new(),
        }
    }
}

/// The exact reference of the base's scene, when it has one.
fn exact_reference(model: &ModelSpec, base: &JobSpec, t_end: f64) -> Result<Reference, SpecError> {
    match model {
        ModelSpec::BouncingBall(b) => Ok(Reference::Ball(b.clone())),
        ModelSpec::DepBar(spec) => dep_bar_reference(spec, t_end),
        ModelSpec::JayNegrutTest(j) if j.y0.is_some() || j.z0.is_some() => Err(SpecError::new(
            "study.reference",
            "the exact solution of jay_negrut_test is for the paper's initial values (no y0, z0)",
        )),
        ModelSpec::JayNegrutTest(_) => Ok(Reference::JayNegrut {
            probes: base.output.probes.clone(),
        }),
        other => Err(no_exact_solution(other.scene())),
    }
}

/// The exact reference of a `dep_bar` (Doyen, Ern & Piperno's bar), which exists for no initial
/// displacement, damping, harmonic force or wall motion, and e = 0.
fn dep_bar_reference(spec: &BarSpec, t_end: f64) -> Result<Reference, SpecError> {
    let bar: Bar = spec.resolve(Bar::doyen_ern_piperno(100));
    if spec.obstacle.is_some()
        || bar.initial_displacement != 0.0
        || bar.rayleigh_mass != 0.0
        || bar.rayleigh_stiffness != 0.0
        || bar.harmonic_force.is_some()
        || bar.wall_motion.is_some()
        || bar.restitution != 0.0
    {
        return Err(SpecError::new(
            "study.reference",
            "the exact solution of dep_bar is for no initial displacement, damping, \
             harmonic force or wall motion, and e = 0",
        ));
    }
    let exact = ExactBar {
        length: bar.length,
        young: bar.young,
        density: bar.density,
        area: bar.area,
        gap: bar.gap,
        body_force: bar.body_force,
        initial_velocity: bar.initial_velocity,
        left: bar.left,
    };
    Ok(Reference::DepBar {
        gap: bar.gap,
        area: bar.area,
        solution: Box::new(ExactSolution::solve(exact, t_end * 1.01 + 1e-9)),
    })
}

/// How a fine reference run is written, for the refusal below.
const FINE_RUN: &str = "reference = { scheme = '...', h = ... }";

/// The refusal of a study without a reference for a scene that has no exact solution.
fn no_exact_solution(scene: &str) -> SpecError {
    SpecError::new(
        "study.reference",
        format!(
            "scene {scene} has no exact solution (bouncing_ball, dep_bar and jay_negrut_test do): \
             give a fine run, {FINE_RUN}"
        ),
    )
}

/// −∫_{ta}^{tb} A r dt of the exact contact force (≥ 0), exactly (r is linear on each piece
/// of the solution by characteristics).
pub fn exact_impulse(exact: &ExactSolution, area: f64, ta: f64, tb: f64) -> f64 {
    let mut sum = 0.0;
    let start = exact.pieces.partition_point(|p| p.t1 <= ta);
    for p in &exact.pieces[start..] {
        if p.t0 >= tb {
            break;
        }
        if !p.contact {
            continue;
        }
        let (a, b) = (ta.max(p.t0), tb.min(p.t1));
        if b > a {
            // ∫ (a0 + a1 (t − t0)) dt over [a, b].
            let mid = 0.5 * (a + b) - p.t0;
            sum += area * (p.a0 + p.a1 * mid) * (b - a);
        }
    }
    -sum
}

/// [`ErrorNorm::ImpulseL1`] of a run's `p_0` against the exact impulses.
fn impulse_error(run: &Samples, exact: &ExactSolution, area: f64) -> Result<f64, SpecError> {
    if run.impulses.len() != run.t.len() {
        return Err(SpecError::new(
            "study.error",
            "impulse_l1 needs the runs' contact impulse p_0 (a scheme that reports it)",
        ));
    }
    let (mut error, mut total) = (0.0, 0.0);
    for k in 1..run.t.len() {
        let exact = exact_impulse(exact, area, run.t[k - 1], run.t[k]);
        error += (run.impulses[k] - exact).abs();
        total += exact;
    }
    Ok(error / total)
}

/// Accumulates a norm of errors e_{k,i}.
struct NormAccumulator {
    norm: ErrorNorm,
    max: f64,
    sum_sq: f64,
    count: usize,
    last_k: usize,
    last_max: f64,
}

impl NormAccumulator {
    fn new(norm: ErrorNorm) -> Self {
        Self {
            norm,
            max: 0.0,
            sum_sq: 0.0,
            count: 0,
            last_k: 0,
            last_max: 0.0,
        }
    }

    fn add(&mut self, k: usize, e: f64) {
        // A NaN error (a diverged run) stays NaN.
        let a = e.abs();
        self.max = if a.is_nan() {
            f64::NAN
        } else {
            self.max.max(a)
        };
        self.sum_sq += e * e;
        self.count += 1;
        if k != self.last_k {
            self.last_k = k;
            self.last_max = 0.0;
        }
        self.last_max = if a.is_nan() {
            f64::NAN
        } else {
            self.last_max.max(a)
        };
    }

    fn finish(self) -> f64 {
        match self.norm {
            ErrorNorm::MaxAbs => self.max,
            ErrorNorm::Rms if self.count > 0 => (self.sum_sq / self.count as f64).sqrt(),
            ErrorNorm::Rms => 0.0,
            ErrorNorm::Final => self.last_max,
            // Computed from the impulses ([`impulse_error`]), never accumulated.
            ErrorNorm::ImpulseL1 => f64::NAN,
        }
    }
}

/// Whether a study compares column `name` of a run's `columns`: a `q_j`, `y_j` or `gap_i`, or a
/// rigid body's position `NAME_x`, `NAME_y`, `NAME_z` (a column `NAME_qw` beside it says that
/// NAME is a body).
fn compared(name: &str, columns: &Columns) -> bool {
    if name.starts_with("q_") || name.starts_with("y_") || name.starts_with("gap_") {
        return true;
    }
    ["_x", "_y", "_z"].iter().any(|axis| {
        name.strip_suffix(axis)
            .is_some_and(|body| columns.index(&format!("{body}_qw")).is_some())
    })
}

/// Records what a study compares: t and the `q_j`, `y_j` and `gap_i` columns (and the bodies'
/// positions, [`compared`]) of every recorded
/// step, and the largest |balance_residual| and |energy_error| (the energy check of the run).
#[derive(Debug, Clone, Default)]
pub struct Samples {
    /// The recorded columns, by name.
    pub names: Vec<String>,
    indices: Vec<usize>,
    /// t of each recorded step.
    pub t: Vec<f64>,
    /// The recorded values, one row per step (in `names` order).
    pub values: Vec<Vec<f64>>,
    /// The contact impulse `p_0` of every recorded step (empty when the run has no `p_0`).
    pub impulses: Vec<f64>,
    impulse: Option<usize>,
    balance: Option<usize>,
    energy_error: Option<usize>,
    /// Largest |balance_residual| (NaN when the scheme reports none).
    pub max_balance_residual: f64,
    /// Largest |energy_error| (NaN when the scheme reports none).
    pub max_energy_error: f64,
}

impl Samples {
    /// Linear interpolation of column `j` at t (held constant outside the recorded range).
    fn at(&self, t: f64, j: usize) -> f64 {
        let k = self.t.partition_point(|&s| s < t);
        if k == 0 {
            return self.values.first().map_or(f64::NAN, |r| r[j]);
        }
        if k >= self.t.len() {
            return self.values.last().map_or(f64::NAN, |r| r[j]);
        }
        let (t0, t1) = (self.t[k - 1], self.t[k]);
        let (x0, x1) = (self.values[k - 1][j], self.values[k][j]);
        if t1 == t0 {
            x1
        } else {
            x0 + (x1 - x0) * (t - t0) / (t1 - t0)
        }
    }
}

impl Observer for Samples {
    fn start(&mut self, columns: &Columns) {
        self.names.clear();
        self.indices.clear();
        for (i, n) in columns.names().iter().enumerate() {
            if compared(n, columns) {
                self.names.push(n.clone());
                self.indices.push(i);
            }
        }
        self.impulse = columns.index("p_0");
        self.impulses.clear();
        self.balance = columns.index("balance_residual");
        self.energy_error = columns.index("energy_error");
        self.max_balance_residual = if self.balance.is_some() {
            0.0
        } else {
            f64::NAN
        };
        self.max_energy_error = if self.energy_error.is_some() {
            0.0
        } else {
            f64::NAN
        };
    }

    fn observe(&mut self, record: &StepRecord<'_>) -> ControlFlow<()> {
        self.t.push(record.t);
        self.values
            .push(self.indices.iter().map(|&i| record.values[i]).collect());
        if let Some(i) = self.impulse {
            self.impulses.push(record.values[i]);
        }
        if let Some(i) = self.balance {
            self.max_balance_residual = self.max_balance_residual.max(record.values[i].abs());
        }
        if let Some(i) = self.energy_error {
            self.max_energy_error = self.max_energy_error.max(record.values[i].abs());
        }
        ControlFlow::Continue(())
    }
}

/// A study spec's base: the inline spec, or `None` when it names a file (read by the caller).
pub fn inline_base(spec: &StudySpec) -> Option<&JobSpec> {
    match &spec.base {
        StudyBase::Inline(b) => Some(b),
        StudyBase::File(_) => None,
    }
}
