//! Pause, resume and extend.
//!
//! * **Pause** parks a job in the state `paused`. A queued job is taken off the queue at once;
//!   a running one is asked to stop (its [`LiveJob::pause`] flag, or with a shared store the
//!   `pause_requested` flag its replica reads at its next heartbeat): its observer asks the run
//!   for a checkpoint after the next step, stores it with the rows recorded up to it, and stops
//!   the run there ([`park`]). A paused job keeps its checkpoint and its series; it is neither
//!   queued nor finished, so no worker takes it, a restart leaves it paused, and the retention
//!   sweep does not expire it.
//! * **Resume** queues a paused job again; a worker (of any replica, with a shared store) takes
//!   it and continues from its checkpoint exactly as after a restart (`resume_point`): the result
//!   equals an uninterrupted run's bit for bit.
//! * **Extend** makes a new job that continues a succeeded job to a later `t_end`. A succeeded
//!   job that checkpoints keeps the checkpoint written after its last step as its final state
//!   (stored with the job's end, `Backend::end`); the new job's spec is the first's with
//!   `time.t_end` set (and `time.steps` cleared), and it starts from that final state, which
//!   the spec hash accepts because it leaves out the run's end
//!   (`signorini_core::job::spec_hash`). Its result holds the rows after the first job's end
//!   (the first job's result holds the rows up to it) and its summary, the whole run's, names
//!   the first job (`extends`).
//!
//! A job whose scheme family writes no checkpoints (`Job::checkpoints`: analyses, the banded
//! contact path, a contact region) is refused: it could only be rerun from step 0.

use super::{Engine, Inner, LiveJob, check_limits, check_text, lock, new_live};
use crate::engine::EngineError;
use crate::engine::events::JobEvent;
use crate::engine::ids::{check_id, new_id, now_ms};
use crate::spec_file::{Format, parse};
use crate::status::{JobState, JobView};
use serde_json::{Map, Value};
use signorini_core::job::Job;
use signorini_core::spec::{SchemeFamily, SpecError};
use std::sync::Arc;
use std::sync::atomic::Ordering;

/// Why a job of this kind cannot be paused or extended.
const NO_CHECKPOINTS: &str = "an analysis (forced response, nonsmooth modes) writes no checkpoints (docs/checkpoints.md), so it could only rerun from step 0";

/// Why a study's parent job cannot be paused or extended.
const NO_RUN_OF_ITS_OWN: &str = "a study has no run of its own: pause, resume or extend its children (GET /v1/jobs/{id}/children)";

/// Parks a running job whose run stopped after its pause checkpoint: the store marks it paused
/// with the progress of that checkpoint, and its watchers get the status. A store that refuses
/// the write fails the job with its reason ([`super::fail_for_store`]), whose end is stored
/// (or kept until it can be) like any other; with a shared store, the worker's next job may
/// come with that end, and is returned.
pub(super) fn park(inner: &Inner, live: &Arc<LiveJob>) -> Option<Arc<LiveJob>> {
    let view = JobView {
        state: JobState::Paused,
        ..live.view()
    };
    match super::noted(inner, inner.store.park(&view)) {
        Ok(true) => tracing::info!(id = %live.id, step = view.done, "paused"),
        Ok(false) => {
            tracing::warn!(id = %live.id, "paused, but the store no longer had it running")
        }
        Err(e) => return super::fail_for_store(inner, live, &e),
    }
    lock(&inner.live).remove(&live.id);
    inner.sink.send(JobEvent::Status(view));
    inner.sink.send(JobEvent::Closed(live.id.clone()));
    live.ended.send_replace(true);
    None
}

/// Names the job an extension continues in its summary (`extends`), as its claim read it from
/// a shared store, or else asking the store.
pub(super) fn mark_extension(inner: &Inner, live: &LiveJob, summary: &mut Map<String, Value>) {
    let id = &live.id;
    let extends = match &live.claimed {
        Some(c) => Ok(c.extends.clone()),
        None => inner.store.extends(id),
    };
    match extends {
        Ok(Some(first)) => {
            summary.insert("extends".into(), Value::String(first));
        }
        Ok(None) => {}
        Err(e) => tracing::error!(%id, "store: {e}"),
    }
}

fn wrong_state(view: &JobView, reason: impl Into<String>) -> EngineError {
    EngineError::WrongState {
        id: view.id.clone(),
        state: view.state.as_str(),
        reason: reason.into(),
    }
}

impl Engine {
    /// A job's spec as stored.
    pub fn stored_spec(&self, id: &str) -> Result<signorini_core::spec::JobSpec, EngineError> {
        let json = self
            .inner
            .store
            .spec_json(id)?
            .ok_or_else(|| EngineError::NotFound { id: id.into() })?;
        Ok(parse(&json, Format::Json)?)
    }

    /// A job's spec as stored, built into a job (the error names the field).
    fn stored_job(&self, id: &str) -> Result<(Job, signorini_core::spec::JobSpec), EngineError> {
        let spec = self.stored_spec(id)?;
        Ok((Job::from_spec(&spec)?, spec))
    }

    /// Pauses a job: a queued one is parked at once (its status, `paused`, is returned); a
    /// running one is asked to stop after a checkpoint at its next step (its status, still
    /// `running`, is returned: await [`Engine::ended`] for the pause). Another state, or a job
    /// that writes no checkpoints, is refused ([`EngineError::WrongState`]).
    pub fn pause(&self, id: &str) -> Result<JobView, EngineError> {
        let live = lock(&self.inner.live).get(id).cloned();
        let Some(live) = live else {
            let view = self.status(id)?;
            if self.inner.store.is_study(id)? {
                return Err(wrong_state(&view, NO_RUN_OF_ITS_OWN));
            }
            return match view.state {
                JobState::Queued | JobState::Running => {
                    // With a shared store: queued for any replica, or running on another one.
                    if !self.stored_job(id)?.0.checkpoints() {
                        return Err(wrong_state(
                            &view,
                            format!("it cannot be paused: {NO_CHECKPOINTS}"),
                        ));
                    }
                    let parked = JobView {
                        state: JobState::Paused,
                        ..view.clone()
                    };
                    if view.state == JobState::Queued && self.inner.store.park(&parked)? {
                        self.inner.sink.send(JobEvent::Status(parked.clone()));
                        return Ok(parked);
                    }
                    if self.inner.store.request_pause(id)? {
                        return Ok(view);
                    }
                    // It moved on meanwhile (claimed, finished): answer for its state now.
                    let now = self.status(id)?;
                    Err(wrong_state(
                        &now,
                        "only a queued or running job can be paused",
                    ))
                }
                JobState::Paused => Err(wrong_state(&view, "it is paused already")),
                _ => Err(wrong_state(
                    &view,
                    "only a queued or running job can be paused",
                )),
            };
        };
        if !live.job.checkpoints() {
            return Err(wrong_state(
                &live.view(),
                format!("it cannot be paused: {NO_CHECKPOINTS}"),
            ));
        }
        if !self.inner.queue.withdraw(id) {
            // Running: its observer checkpoints after the next step and stops the run.
            live.stop.ask(super::stop::StopReason::Pause);
            return Ok(live.view());
        }
        let view = JobView {
            state: JobState::Paused,
            ..live.view()
        };
        self.inner.store.park(&view)?;
        lock(&self.inner.live).remove(id);
        self.inner.sink.send(JobEvent::Status(view.clone()));
        self.inner.sink.send(JobEvent::Closed(id.to_string()));
        live.ended.send_replace(true);
        tracing::info!(%id, "paused while queued");
        Ok(view)
    }

    /// Queues a paused job again: it continues from its checkpoint (or starts, if it was paused
    /// before it ran). Its status, now `queued`. Another state is refused
    /// ([`EngineError::WrongState`]).
    pub fn resume(&self, id: &str) -> Result<JobView, EngineError> {
        if self.inner.shutdown.load(Ordering::Acquire) {
            return Err(EngineError::Unavailable);
        }
        // Checked before the job leaves `paused`, so a refused resume changes nothing.
        if self.inner.queue.depth()? >= self.inner.queue_limit {
            return Err(super::queue::full(&self.inner));
        }
        let Some((view, spec_json)) = self.inner.store.unpark(id)? else {
            let view = self.status(id)?;
            return Err(wrong_state(&view, "only a paused job can be resumed"));
        };
        tracing::info!(%id, step = view.done, "resumed: queued again");
        self.inner.queue.resumed(&self.inner, view, &spec_json)
    }

    /// Cancels a paused job (called by [`Engine::cancel`] for a job this process does not hold):
    /// its status, now `cancelled`; `None` when the job is not paused.
    pub(super) fn cancel_paused(&self, id: &str) -> Result<Option<JobView>, EngineError> {
        let Some(view) = self.inner.store.cancel_parked(id, now_ms())? else {
            return Ok(None);
        };
        tracing::info!(%id, "cancelled while paused");
        self.inner.sink.send(JobEvent::Status(view.clone()));
        self.inner.sink.send(JobEvent::Closed(id.to_string()));
        // A study's child counts as ended for its parent.
        super::study::child_ended(&self.inner, id);
        Ok(Some(view))
    }

    /// Refuses to remove a paused job (cancel it first), as for a queued or running one.
    pub(super) fn refuse_paused_delete(&self, id: &str) -> Result<(), EngineError> {
        match self.inner.store.get(id)? {
            Some(v) if v.state == JobState::Paused => Err(EngineError::Unfinished {
                id: id.into(),
                state: v.state.as_str(),
            }),
            _ => Ok(()),
        }
    }

    /// A new job continuing succeeded job `id` from its final state to `t_end` (with id
    /// `new_id` if given): its id. `t_end` must lie after the first job's end, by one step at
    /// least (else [`EngineError::Invalid`] naming `t_end`); the first job must have succeeded and
    /// kept its final state (else [`EngineError::WrongState`]).
    pub fn extend(
        &self,
        id: &str,
        t_end: f64,
        chosen: Option<String>,
    ) -> Result<String, EngineError> {
        if self.inner.shutdown.load(Ordering::Acquire) {
            return Err(EngineError::Unavailable);
        }
        if let Some(n) = &chosen {
            check_id(n)?;
        }
        let first = self.status(id)?;
        if self.inner.store.is_study(id)? {
            return Err(wrong_state(&first, NO_RUN_OF_ITS_OWN));
        }
        if first.state != JobState::Succeeded {
            return Err(wrong_state(&first, "only a succeeded job can be extended"));
        }
        let (first_job, spec) = self.stored_job(id)?;
        let Some((step, bytes)) = self.inner.store.final_state(id)? else {
            let reason = if first_job.checkpoints() {
                "it kept no final state (it ended before this server kept final states)".to_string()
            } else {
                format!("it cannot be extended: {NO_CHECKPOINTS}")
            };
            return Err(wrong_state(&first, reason));
        };
        match spec.integrator.family() {
            SchemeFamily::Soi2 => {
                return Err(wrong_state(
                    &first,
                    "an SOI2 job cannot be extended bit for bit: its last step is shortened to land on t_end, so a run to a later t_end parts from it there; submit the longer run instead",
                ));
            }
            SchemeFamily::Wave if !step.is_multiple_of(spec.output.every.max(1)) => {
                return Err(wrong_state(
                    &first,
                    format!(
                        "a WFEM job extends from a recorded step only: it ended on step {step}, not a multiple of output.every = {} (WFEM sums the works since the last record)",
                        spec.output.every
                    ),
                ));
            }
            _ if first_job.draws_contact_region() => {
                return Err(wrong_state(
                    &first,
                    "a job drawing a contact region cannot be extended bit for bit: the chart's time buckets are sized by the run's length, so a run to a later t_end draws another grid; submit the longer run instead",
                ));
            }
            _ => {}
        }
        if !(t_end.is_finite() && t_end > first.t) {
            return Err(SpecError::new(
                "t_end",
                format!(
                    "must be after the end of job {id} (t = {}), got {t_end}",
                    first.t
                ),
            )
            .into());
        }
        let mut next = spec;
        let time = next
            .time
            .as_mut()
            .ok_or_else(|| EngineError::Internal(format!("job {id} has no time section")))?;
        time.t_end = Some(t_end);
        time.steps = None;
        let job = Job::from_spec(&next)?;
        if job.size().steps <= step {
            return Err(SpecError::new(
                "t_end",
                format!(
                    "{t_end} adds no step after the end of job {id} (step {step}, t = {})",
                    first.t
                ),
            )
            .into());
        }
        // The final state must continue the new job (the same spec but for its end).
        job.read_checkpoint(&bytes)
            .map_err(|e| EngineError::Internal(format!("the final state of job {id}: {e}")))?;
        let spec_value =
            serde_json::to_value(&next).map_err(|e| EngineError::Internal(e.to_string()))?;
        check_text(&spec_value, "")?;
        check_limits(&job, &self.inner.limits)?;
        let spec_json = spec_value.to_string();
        let new = chosen.unwrap_or_else(new_id);
        let live = Arc::new(new_live(
            new.clone(),
            next.name.clone(),
            job,
            now_ms(),
            false,
        ));
        // Inserted paused (no worker takes it), linked to the job it continues, then queued.
        let parked = JobView {
            state: JobState::Paused,
            ..live.view()
        };
        self.inner.queue.enqueue(&self.inner, &[live], &mut || {
            if !self.inner.store.insert(&parked, &spec_json)? {
                return Err(EngineError::AlreadyExists { id: new.clone() });
            }
            self.link(id, &new)?;
            self.inner.store.unpark(&new)?;
            Ok(())
        })?;
        tracing::info!(%id, extension = %new, t_end, "extended");
        Ok(new)
    }

    /// Links extension `new` to job `first`, or removes `new` again when `first`'s final state
    /// went meanwhile (purged).
    fn link(&self, first: &str, new: &str) -> Result<(), EngineError> {
        if self.inner.store.link_extension(first, new)? {
            return Ok(());
        }
        // A shared store removes finished jobs only: the parked one is cancelled first.
        self.inner.store.cancel_parked(new, now_ms())?;
        self.inner.store.delete(new)?;
        Err(EngineError::NotFound { id: first.into() })
    }
}
