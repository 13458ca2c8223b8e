//! Why a run stops before its end: asked of a running job by a client or the heartbeat
//! ([`StopRequest`]), and recorded by the run's observer at the moment it breaks the run
//! ([`StopReason`]), so the worker reads what happened instead of inferring it from flags
//! after `RunError::Stopped`.

use std::sync::atomic::{AtomicU8, Ordering};

/// Why the engine's observer stopped a run, weakest first: a stronger reason asked while a
/// weaker one is pending replaces it (a cancel overrides a pause, a lost lease everything).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub(super) enum StopReason {
    /// The server shuts down: the job goes back to the queue, to continue from the checkpoint
    /// written just before (or from step 0 for a run that writes none).
    Shutdown = 1,
    /// A client paused the job: it stopped after the checkpoint of its next step and is parked.
    Pause = 2,
    /// The run took longer than the server's `max_wall_seconds`: it ends `failed` naming the
    /// limit, with what it recorded kept as partial.
    WallLimit = 3,
    /// The run held more memory than the server's `max_memory_mb`: it ends `failed` naming the
    /// limit, with what it recorded kept as partial.
    MemoryLimit = 4,
    /// A client cancelled the job: it ends `cancelled`, with what it recorded kept as partial.
    Cancel = 5,
    /// Another replica claimed the job again (this one did not renew its lease in time): this
    /// replica stores nothing more of it.
    LeaseLost = 6,
}

impl StopReason {
    fn of(code: u8) -> Option<StopReason> {
        [
            StopReason::Shutdown,
            StopReason::Pause,
            StopReason::WallLimit,
            StopReason::MemoryLimit,
            StopReason::Cancel,
            StopReason::LeaseLost,
        ]
        .into_iter()
        .find(|r| *r as u8 == code)
    }
}

/// The stop asked of one job, read by its run's observer after every step.
#[derive(Debug, Default)]
pub(super) struct StopRequest(AtomicU8);

impl StopRequest {
    /// Asks the run to stop for `reason`, unless a stronger reason was asked already.
    pub(super) fn ask(&self, reason: StopReason) {
        self.0.fetch_max(reason as u8, Ordering::AcqRel);
    }

    /// The strongest reason asked so far.
    pub(super) fn asked(&self) -> Option<StopReason> {
        StopReason::of(self.0.load(Ordering::Acquire))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stronger_reason_replaces_a_weaker_one() {
        let stop = StopRequest::default();
        assert_eq!(stop.asked(), None);
        stop.ask(StopReason::Pause);
        assert_eq!(stop.asked(), Some(StopReason::Pause));
        stop.ask(StopReason::Cancel);
        assert_eq!(stop.asked(), Some(StopReason::Cancel));
        stop.ask(StopReason::Pause);
        assert_eq!(stop.asked(), Some(StopReason::Cancel));
        stop.ask(StopReason::LeaseLost);
        stop.ask(StopReason::Cancel);
        assert_eq!(stop.asked(), Some(StopReason::LeaseLost));
    }
}
