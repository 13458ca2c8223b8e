//! Running a study (`[study]`): the reference, then every run on a pool of threads, each timed
//! in CPU seconds of its own thread (the core expands and judges; it has no clock).

use crate::spec_file::{self, Format};
use anyhow::{Context, Result, anyhow};
use cpu_time::ThreadTime;
use signorini_core::job;
use signorini_core::spec::JobSpec;
use signorini_core::spec::SpecError;
use signorini_core::spec::study::StudyBase;
use signorini_core::study::{Reference, Samples, Study, StudyPoint, StudyReport, StudyRun};
use std::path::Path;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

/// The base spec of a study: inline, or the file it names, relative to `dir` (the study file's
/// directory).
pub fn base_spec(spec: &JobSpec, dir: Option<&Path>) -> Result<JobSpec> {
    let study = spec.study.as_ref().ok_or_else(|| anyhow!("not a study"))?;
    match &study.base {
        StudyBase::Inline(b) => Ok((**b).clone()),
        StudyBase::File(name) => {
            let dir = dir.ok_or_else(|| {
                anyhow!("study.base: a file name needs a study file; give the base inline ([study.base])")
            })?;
            let path = dir.join(name);
            let text = std::fs::read_to_string(&path)
                .with_context(|| format!("study.base: reading {}", path.display()))?;
            spec_file::parse(&text, Format::of_path(&path))
                .map_err(|e| anyhow!("study.base ({}): {e}", path.display()))
        }
    }
}

/// What one run of a study gives: its samples, its steps and its CPU seconds.
pub struct Measured {
    /// The compared columns of every recorded step.
    pub samples: Samples,
    /// Steps taken.
    pub steps: u64,
    /// CPU seconds of the run's thread.
    pub cpu_s: f64,
}

/// Runs `job` with a [`Samples`] observer on this thread, timed in CPU seconds of the thread.
fn run_one(job: &job::Job) -> Result<Measured, String> {
    let mut samples = Samples::default();
    let started = ThreadTime::now();
    job::run_with_detectors(
        job,
        1,
        &mut samples,
        None,
        &signorini_collision::ParryDetectors,
    )
    .map_err(|e| e.to_string())?;
    let cpu_s = started.elapsed().as_secs_f64();
    Ok(Measured {
        samples,
        steps: job.size().steps,
        cpu_s,
    })
}

/// The base spec of a study the service runs: inline only (a file name is on the client's
/// machine, not the server's).
pub fn inline_base(spec: &JobSpec) -> Result<JobSpec, SpecError> {
    let study = spec
        .study
        .as_ref()
        .ok_or_else(|| SpecError::new("study", "missing section"))?;
    match &study.base {
        StudyBase::Inline(b) => Ok((**b).clone()),
        StudyBase::File(name) => Err(SpecError::new(
            "study.base",
            format!(
                "the service takes the base spec inline ([study.base] or \"base\": {{…}}); \
                 {name:?} names a file, which the server cannot read (`signorini run` reads it)"
            ),
        )),
    }
}

/// The point of one run of `study`: its error against the reference (the reference run's
/// samples when it is one), or, for a run that failed (`Err` with why), a row with an empty
/// error, CPU time and steps. The CLI and the service both make every point here.
pub fn point(
    study: &Study,
    run: &StudyRun,
    outcome: Result<&Measured, &str>,
    reference: Option<&Samples>,
) -> Result<StudyPoint, SpecError> {
    match outcome {
        Ok(m) => {
            let error = study.error(&m.samples, reference)?;
            Ok(StudyPoint::new(
                run,
                m.steps,
                m.cpu_s,
                error,
                Some(&m.samples),
            ))
        }
        Err(_) => Ok(StudyPoint::new(run, 0, f64::NAN, f64::NAN, None)),
    }
}

/// The outputs of a study: `study.csv` (text, for the CLI), the `study` table (numbers, for
/// the service), the `work_precision` figure and `summary.json`.
pub struct Outputs {
    /// `study.csv`.
    pub csv: String,
    /// The numeric table [`StudyReport::table`].
    pub table: signorini_core::outcome::Table,
    /// `work_precision.svg`.
    pub figures: Vec<signorini_figures::Figure>,
    /// `summary.json`.
    pub summary: serde_json::Map<String, serde_json::Value>,
}

/// The outputs of `report`.
pub fn outputs(report: &StudyReport) -> Result<Outputs> {
    let summary = match serde_json::to_value(report.summary())? {
        serde_json::Value::Object(map) => map,
        other => return Err(anyhow!("a study summary is an object, got {other}")),
    };
    Ok(Outputs {
        csv: report.csv(),
        table: report.table(),
        figures: signorini_figures::render(&[report.chart()]),
        summary,
    })
}

/// Expands and runs the study of `spec` on `threads` threads; `progress` hears one line per
/// finished run. A run that fails keeps its point with a NaN error (and says why).
pub fn run_study(
    spec: &JobSpec,
    dir: Option<&Path>,
    threads: usize,
    progress: &(dyn Fn(String) + Sync),
) -> Result<StudyReport> {
    let base = base_spec(spec, dir)?;
    let study_spec = spec.study.as_ref().ok_or_else(|| anyhow!("not a study"))?;
    let study = Study::from_spec(study_spec, &base).map_err(|e| anyhow!("{e}"))?;
    let reference = match &study.reference {
        Reference::Run(job) => {
            progress(format!(
                "reference: {}",
                study.reference.describe(&study_spec.reference)
            ));
            let m = run_one(job).map_err(|e| anyhow!("study.reference: the run failed: {e}"))?;
            progress(format!("reference done ({:.3} s CPU)", m.cpu_s));
            Some(m.samples)
        }
        _ => None,
    };
    let total = study.runs.len();
    let next = AtomicUsize::new(0);
    let points: Mutex<Vec<Option<StudyPoint>>> = Mutex::new(vec![None; total]);
    let failure: Mutex<Option<anyhow::Error>> = Mutex::new(None);
    std::thread::scope(|scope| {
        for _ in 0..threads.clamp(1, total.max(1)) {
            scope.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    let Some(run) = study.runs.get(i) else { break };
                    let at: Vec<String> = study
                        .axes
                        .iter()
                        .zip(&run.values)
                        .map(|(a, v)| format!("{a}={v}"))
                        .collect();
                    let outcome = run_one(&run.job);
                    let point = match point(
                        &study,
                        run,
                        outcome.as_ref().map_err(String::as_str),
                        reference.as_ref(),
                    ) {
                        Ok(p) => p,
                        Err(e) => {
                            failure.lock().map(|mut f| *f = Some(anyhow!("{e}"))).ok();
                            StudyPoint::new(run, 0, f64::NAN, f64::NAN, None)
                        }
                    };
                    match &outcome {
                        Ok(m) => progress(format!(
                            "run {}/{total} {} {}: error {:.3e}, {:.4} s CPU",
                            i + 1,
                            run.label,
                            at.join(" "),
                            point.error,
                            m.cpu_s
                        )),
                        Err(e) => progress(format!(
                            "run {}/{total} {} {}: failed: {e}",
                            i + 1,
                            run.label,
                            at.join(" ")
                        )),
                    }
                    if let Ok(mut p) = points.lock() {
                        p[i] = Some(point);
                    }
                }
            });
        }
    });
    if let Some(e) = failure.into_inner().ok().flatten() {
        return Err(e);
    }
    let points = points
        .into_inner()
        .map_err(|_| anyhow!("a study thread panicked"))?
        .into_iter()
        .collect::<Option<Vec<_>>>()
        .ok_or_else(|| anyhow!("a study run did not report"))?;
    Ok(StudyReport::new(&study, points))
}
