//! What the store does for pause, resume and extend (`crate::engine::pause`), both backends:
//! a paused job's row (state `paused`, its progress), the final state a succeeded job keeps so
//! that it can be extended, and the link of an extension to the job it continues.
//!
//! A paused job is neither queued nor finished: no worker claims it, [`super::Backend::recover`]
//! leaves it paused, the retention sweep ([`super::Backend::finished_before`]) does not expire
//! it, and its checkpoint and recorded series stay until it is resumed, cancelled or (after a
//! cancel) purged.

use super::StoreError;
use crate::status::JobView;

/// The pause, resume and extend part of a store (a supertrait of [`super::Backend`]).
pub trait PauseStore {
    /// Parks a queued job, or a running one this process (replica) holds, as paused with the
    /// progress of `row` (`done`, `total`, `t`); a shared store also gives up the lease. False
    /// when the job was in neither state.
    fn park(&self, row: &JobView) -> Result<bool, StoreError>;

    /// Queues a paused job again (announced to every replica with a shared store): its status,
    /// now queued, and its spec (JSON); `None` when the job is not paused.
    fn unpark(&self, id: &str) -> Result<Option<(JobView, String)>, StoreError>;

    /// Cancels a paused job at `finished_ms`, dropping its checkpoint and recorded rows: its
    /// status, now cancelled; `None` when the job is not paused.
    fn cancel_parked(&self, id: &str, finished_ms: u64) -> Result<Option<JobView>, StoreError>;

    /// Asks the replica running job `id` to pause it at its next heartbeat (a shared store; the
    /// single-process store has no other runner and answers false). False when the job is not
    /// running.
    fn request_pause(&self, _id: &str) -> Result<bool, StoreError> {
        Ok(false)
    }

    /// Keeps the checkpoint of a job that has just succeeded as its final state, when that
    /// checkpoint was written after its last step `step` (a job extended later continues from
    /// it). True when it was kept. The running checkpoint itself is deleted by the caller.
    fn keep_final_state(&self, id: &str, step: u64) -> Result<bool, StoreError>;

    /// The final state a succeeded job kept: (step, checkpoint bytes).
    fn final_state(&self, id: &str) -> Result<Option<(u64, Vec<u8>)>, StoreError>;

    /// Makes job `to` (inserted, not yet runnable) a continuation of job `from`: `from`'s final
    /// state becomes `to`'s checkpoint (attempt 0) and `to` records that it extends `from`, in
    /// one transaction. False when `from` kept no final state.
    fn link_extension(&self, from: &str, to: &str) -> Result<bool, StoreError>;

    /// The job that job `id` extends, if it is an extension.
    fn extends(&self, id: &str) -> Result<Option<String>, StoreError>;

    /// A job's spec (JSON), if the job exists.
    fn spec_json(&self, id: &str) -> Result<Option<String>, StoreError>;
}
