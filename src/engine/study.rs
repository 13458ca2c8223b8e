//! Studies (`[study]`) as service jobs: a parent job that fans out into child jobs.
//!
//! Submitting a study expands it (`Study::from_spec`, the base inline) and records, in one
//! store transaction, the parent — `running`, its `total` the number of children, its spec the
//! study — and one ordinary queued job per run (and one for the reference run, if the study
//! has one, first). The children run on the pool like any job (on a shared store, on any
//! replica), each timing itself in CPU seconds of its worker thread (`cpu_s` in its summary).
//!
//! The parent has no worker. Whenever a job ends, the store counts the ended children of its
//! parent, if any (the parent's progress, sent as a status event); the worker that sees the
//! count reach the total computes the report from the children's stored series — the same
//! `crate::study::point` and `StudyReport` as `signorini run` — and completes the parent with a
//! conditional update, so of two workers (or replicas) that both see the end, one writes it. A
//! sweep at start-up and every [`SWEEP_EVERY`] completes a parent whose last child ended on a
//! replica that died, or before a restart, before it could.
//!
//! Cancelling the parent cancels its queued and running children and ends the parent
//! `cancelled` (no result). Purging a finished parent purges its children with it.

use super::{Engine, Inner, JobEvent, MAX_NAME_BYTES, check_limits, lock, new_live, now_ms};
use crate::engine::EngineError;
use crate::spec_file::{self, Format};
use crate::status::{JobState, JobView};
use crate::store::StoredResult;
use crate::study::{Measured, inline_base, outputs, point};
use signorini_core::observer::{Columns, Observer, StepRecord};
use signorini_core::spec::{JobSpec, SpecError};
use signorini_core::study::{Reference, Samples, Study, StudyReport, StudyRun};
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::ids::new_id;

/// How often a replica looks for parents whose children have all ended.
pub const SWEEP_EVERY: Duration = Duration::from_secs(2);

/// The name of a child: the scheme and the grid values, within [`MAX_NAME_BYTES`].
fn child_name(study: &Study, run: &StudyRun) -> String {
    let at: Vec<String> = study
        .axes
        .iter()
        .zip(&run.values)
        .map(|(a, v)| format!("{a}={v}"))
        .collect();
    let mut name = if at.is_empty() {
        run.label.clone()
    } else {
        format!("{} [{}]", run.label, at.join(", "))
    };
    if name.len() > MAX_NAME_BYTES {
        let mut cut = MAX_NAME_BYTES;
        while !name.is_char_boundary(cut) {
            cut -= 1;
        }
        name.truncate(cut);
    }
    name
}

/// Expands a study and queues its children under a new parent job. Returns the parent's id.
pub(super) fn submit(
    engine: &Engine,
    spec: &JobSpec,
    spec_json: String,
    id: Option<String>,
) -> Result<String, EngineError> {
    let inner = &engine.inner;
    let base = inline_base(spec)?;
    let study_spec = spec
        .study
        .as_ref()
        .ok_or_else(|| SpecError::new("study", "missing section"))?;
    let study = Study::from_spec(study_spec, &base)?;
    let mut jobs: Vec<(String, &signorini_core::job::Job)> = Vec::new();
    if let Reference::Run(job) = &study.reference {
        jobs.push(("reference".into(), job));
    }
    for run in &study.runs {
        jobs.push((child_name(&study, run), &run.job));
    }
    for (k, (name, job)) in jobs.iter().enumerate() {
        check_limits(job, &inner.limits).map_err(|e| {
            SpecError::new(format!("study: run {k} ({name}): {}", e.field), e.reason)
        })?;
    }
    if jobs.len() > inner.queue_limit {
        return Err(SpecError::new(
            "study",
            format!(
                "{} runs, more than this server's queue holds ({} jobs, --queue-limit): split \
                 the study, or run it with `signorini run`",
                jobs.len(),
                inner.queue_limit
            ),
        )
        .into());
    }
    let id = id.unwrap_or_else(new_id);
    let created_ms = now_ms();
    let lives: Vec<Arc<super::LiveJob>> = jobs
        .iter()
        .map(|(name, job)| {
            Arc::new(new_live(
                new_id(),
                Some(name.clone()),
                (*job).clone(),
                created_ms,
                true,
            ))
        })
        .collect();
    let children: Vec<(JobView, String)> = lives
        .iter()
        .map(|l| {
            serde_json::to_string(l.job.spec())
                .map(|s| (l.view(), s))
                .map_err(|e| EngineError::Internal(e.to_string()))
        })
        .collect::<Result<_, _>>()?;
    let parent = JobView {
        id: id.clone(),
        name: spec.name.clone().or_else(|| base.name.clone()),
        state: JobState::Running,
        done: 0,
        total: children.len() as u64,
        t: 0.0,
        error: None,
        created_ms,
        started_ms: created_ms,
        finished_ms: 0,
    };
    inner.queue.enqueue(inner, &lives, &mut || {
        if !inner.store.insert_study(&parent, &spec_json, &children)? {
            return Err(EngineError::AlreadyExists { id: id.clone() });
        }
        inner.sink.send(JobEvent::Status(parent.clone()));
        Ok(())
    })?;
    tracing::info!(%id, runs = lives.len(), "study queued");
    Ok(id)
}

/// A job ended: if it is a study's child, its parent's progress goes out, and the parent is
/// completed when it was the last.
pub(super) fn child_ended(inner: &Inner, id: &str) {
    match inner.store.child_ended(id) {
        Ok(Some(parent)) => {
            let last = parent.done >= parent.total;
            let parent_id = parent.id.clone();
            inner.sink.send(JobEvent::Status(parent));
            if last {
                complete(inner, &parent_id);
            }
        }
        Ok(None) => {}
        Err(e) => tracing::error!(%id, "store: {e}"),
    }
}

/// A child's samples, steps and CPU seconds from its stored result and series.
fn measured(inner: &Inner, child: &JobView, run_steps: u64) -> Result<Measured, String> {
    if child.state != JobState::Succeeded {
        return Err(match &child.error {
            Some((f, r)) => format!("{}: {f}: {r}", child.state.as_str()),
            None => child.state.as_str().to_string(),
        });
    }
    let head = inner
        .store
        .result_head(&child.id)
        .map_err(|e| e.to_string())?
        .ok_or_else(|| format!("the result of {} is missing", child.id))?;
    let cpu_s = head
        .summary
        .get("cpu_s")
        .and_then(serde_json::Value::as_f64)
        .unwrap_or(f64::NAN);
    let mut samples = Samples::default();
    samples.start(&Columns::new(head.columns.clone()));
    let n = head.columns.len();
    for meta in inner
        .store
        .series_index(&child.id)
        .map_err(|e| e.to_string())?
    {
        let chunk = inner
            .store
            .read_chunk(&child.id, &meta, n)
            .map_err(|e| e.to_string())?;
        for (k, (&step, &t)) in chunk.steps.iter().zip(&chunk.t).enumerate() {
            let _ = samples.observe(&StepRecord {
                step,
                t,
                values: &chunk.values[k * n..(k + 1) * n],
            });
        }
    }
    Ok(Measured {
        samples,
        steps: run_steps,
        cpu_s,
    })
}

/// The report of parent `id` from its children, as its result; the field and reason when the
/// study cannot be reported (the reference run failed, an error cannot be computed).
fn report(inner: &Inner, id: &str, children: &[JobView]) -> Result<StoredResult, (String, String)> {
    let internal = |e: String| ("study".to_string(), e);
    let spec_json = inner
        .store
        .study_spec(id)
        .map_err(|e| internal(e.to_string()))?
        .ok_or_else(|| internal(format!("the spec of {id} is missing")))?;
    let spec = spec_file::parse(&spec_json, Format::Json)
        .map_err(|e| internal(format!("the stored spec no longer parses: {e}")))?;
    let base = inline_base(&spec).map_err(|e| (e.field, e.reason))?;
    let study_spec = spec
        .study
        .as_ref()
        .ok_or_else(|| internal("the stored spec has no [study]".into()))?;
    let study = Study::from_spec(study_spec, &base).map_err(|e| (e.field, e.reason))?;
    let has_reference = matches!(study.reference, Reference::Run(_));
    let expected = study.runs.len() + usize::from(has_reference);
    if children.len() != expected {
        return Err(internal(format!(
            "{} of its {expected} runs are in the store (a child was purged?)",
            children.len()
        )));
    }
    let reference = if has_reference {
        let m = measured(inner, &children[0], 0).map_err(|e| {
            (
                "study.reference".to_string(),
                format!("the reference run {} failed: {e}", children[0].id),
            )
        })?;
        Some(m.samples)
    } else {
        None
    };
    let runs = &children[usize::from(has_reference)..];
    let points = study
        .runs
        .iter()
        .zip(runs)
        .map(|(run, child)| {
            let m = measured(inner, child, run.job.size().steps);
            point(
                &study,
                run,
                m.as_ref().map_err(String::as_str),
                reference.as_ref(),
            )
        })
        .collect::<Result<Vec<_>, SpecError>>()
        .map_err(|e| (e.field, e.reason))?;
    let report = StudyReport::new(&study, points);
    let out = outputs(&report).map_err(|e| internal(e.to_string()))?;
    Ok(StoredResult {
        summary: out.summary,
        tables: vec![out.table],
        figures: out.figures,
        ..StoredResult::default()
    })
}

/// Completes parent `id` (its children have all ended) with its report, unless it ended
/// already; tells the world when this call ended it.
fn complete(inner: &Inner, id: &str) {
    let clock = Instant::now();
    let (children, view) = match (inner.store.children(id), inner.store.get(id)) {
        (Ok(c), Ok(Some(v))) => (c, v),
        (Err(e), _) | (_, Err(e)) => {
            tracing::error!(%id, "store: {e}");
            return;
        }
        (_, Ok(None)) => return,
    };
    if view.state != JobState::Running || children.iter().any(|c| !c.state.is_terminal()) {
        return;
    }
    let ended = children.len() as u64;
    let (state, error, result) = match report(inner, id, &children) {
        Ok(result) => (JobState::Succeeded, None, Some(result)),
        Err(e) => (JobState::Failed, Some(e), None),
    };
    let view = JobView {
        state,
        error,
        done: ended,
        total: ended,
        finished_ms: now_ms(),
        ..view
    };
    // A refused end is tried again by the sweeper (`sweep`), the parent still running.
    match super::noted(inner, inner.store.finish_study(&view, result.as_ref())) {
        Ok(true) => {
            tracing::info!(
                %id,
                state = view.state.as_str(),
                report_s = clock.elapsed().as_secs_f64(),
                "study finished"
            );
            inner.sink.send(JobEvent::Status(view));
            inner.sink.send(JobEvent::Closed(id.to_string()));
        }
        Ok(false) => {}
        Err(e) => tracing::error!(%id, "store: {e}"),
    }
}

/// Completes every parent whose children have all ended.
fn sweep(inner: &Inner) {
    match inner.store.studies_to_finish() {
        Ok(ids) => {
            for id in ids {
                complete(inner, &id);
            }
        }
        Err(e) => tracing::error!("store: {e}"),
    }
}

/// Starts the sweep thread (a first sweep at once).
pub(super) fn spawn_sweeper(engine: &Engine) -> Result<JoinHandle<()>, EngineError> {
    let inner = engine.inner.clone();
    std::thread::Builder::new()
        .name("signorini-studies".into())
        .spawn(move || {
            let mut last: Option<Instant> = None;
            while !inner.shutdown.load(Ordering::Acquire) {
                if last.is_none_or(|l| l.elapsed() >= SWEEP_EVERY) {
                    last = Some(Instant::now());
                    sweep(&inner);
                }
                std::thread::sleep(Duration::from_millis(50));
            }
        })
        .map_err(|e| EngineError::Internal(format!("spawning the study sweep: {e}")))
}

impl Engine {
    /// The children of a study's parent job, in study order (the reference run first, if
    /// any); empty for any other job.
    pub fn children(&self, id: &str) -> Result<Vec<JobView>, EngineError> {
        // The parent must exist (a live child has a stored row too).
        self.status(id)?;
        let live = lock(&self.inner.live);
        Ok(self
            .inner
            .store
            .children(id)?
            .into_iter()
            .map(|v| live.get(&v.id).map_or(v, |l| l.view()))
            .collect())
    }

    /// Cancels a study's parent job: its queued and running children are cancelled and it
    /// ends `cancelled`. `None` when `id` is no study.
    pub(super) fn cancel_study(&self, id: &str) -> Result<Option<JobView>, EngineError> {
        if !self.inner.store.is_study(id)? {
            return Ok(None);
        }
        let view = self
            .inner
            .store
            .get(id)?
            .ok_or_else(|| EngineError::NotFound { id: id.into() })?;
        if view.state.is_terminal() {
            return Ok(Some(view));
        }
        let children = self.inner.store.children(id)?;
        let view = JobView {
            state: JobState::Cancelled,
            finished_ms: now_ms(),
            ..view
        };
        // Ended first, so the children's ends do not complete it meanwhile.
        if self.inner.store.finish_study(&view, None)? {
            self.inner.sink.send(JobEvent::Status(view.clone()));
            self.inner.sink.send(JobEvent::Closed(id.to_string()));
        }
        for child in children.iter().filter(|c| !c.state.is_terminal()) {
            if let Err(e) = self.cancel(&child.id) {
                tracing::warn!(id = %child.id, "cancelling a study's child: {e}");
            }
        }
        Ok(Some(self.inner.store.get(id)?.unwrap_or(view)))
    }

    /// Before a study's parent is purged: its children are purged (it must have ended).
    pub(super) fn delete_children(&self, id: &str) -> Result<(), EngineError> {
        if !self.inner.store.is_study(id)? {
            return Ok(());
        }
        let view = self.status(id)?;
        if !view.state.is_terminal() {
            return Err(EngineError::Unfinished {
                id: id.into(),
                state: view.state.as_str(),
            });
        }
        for child in self.inner.store.children(id)? {
            match self.delete(&child.id) {
                Ok(()) | Err(EngineError::NotFound { .. }) => {}
                Err(e) => return Err(e),
            }
        }
        Ok(())
    }
}
