//! Running a study (`[study]`): the reference, then every run on a pool of threads, each timed
//! in CPU seconds of its own thread (the core expands and judges; it has no clock).

use crate::spec_file::{self, Format};
use anyhow::{Context, Result, anyhow};
use cpu_time::ThreadTime;
use signorini_core::job;
use signorini_core::spec::JobSpec;
use signorini_core::spec::study::StudyBase;
use signorini_core::study::{Reference, Samples, Study, StudyPoint, StudyReport};
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

/// Runs `job` with a [`Samples`] observer on this thread: (samples, steps, CPU seconds).
fn run_one(job: &job::Job) -> Result<(Samples, u64, f64), String> {
    let mut samples = Samples::default();
    let started = ThreadTime::now();
    job::run(job, 1, &mut samples).map_err(|e| e.to_string())?;
    let cpu = started.elapsed().as_secs_f64();
    Ok((samples, job.size().steps, cpu))
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
            let (samples, _, cpu) =
                run_one(job).map_err(|e| anyhow!("study.reference: the run failed: {e}"))?;
            progress(format!("reference done ({cpu:.3} s CPU)"));
            Some(samples)
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
                    let point = match run_one(&run.job) {
                        Ok((samples, steps, cpu_s)) => {
                            let error = match study.error(&samples, reference.as_ref()) {
                                Ok(e) => e,
                                Err(e) => {
                                    failure.lock().map(|mut f| *f = Some(anyhow!("{e}"))).ok();
                                    f64::NAN
                                }
                            };
                            progress(format!(
                                "run {}/{total} {} {}: error {error:.3e}, {cpu_s:.4} s CPU",
                                i + 1,
                                run.label,
                                at.join(" ")
                            ));
                            StudyPoint::new(run, steps, cpu_s, error, Some(&samples))
                        }
                        Err(e) => {
                            progress(format!(
                                "run {}/{total} {} {}: failed: {e}",
                                i + 1,
                                run.label,
                                at.join(" ")
                            ));
                            StudyPoint::new(run, 0, f64::NAN, f64::NAN, None)
                        }
                    };
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
