//! The job-state transition table: which change of state ([`Transition`]) is legal from which
//! states ([`JobState`]) and leads to which, written once. Both stores build the state checks
//! of their SQL from it ([`Transition::from_sql`], [`Transition::to_sql`], [`in_sql`],
//! [`is_sql`]), so no state name is spelled in a statement anywhere else, and the lists of
//! ended and active states ([`ENDED`], [`ACTIVE`]) are these two constants.
//!
//! ```text
//!            submit            claim / start                 end
//!   (none) ─────────► queued ───────────────► running ─────────────► succeeded | failed | cancelled
//!                      │  ▲ ◄─── release ────── │ ▲ takeover (lease ran out, shared queue)
//!              cancel  │  │ resume              │ └──┘
//!                      ▼  │                     ▼ pause
//!                cancelled paused ◄─────────────┘
//!                            │ cancel
//!                            ▼
//!                        cancelled
//! ```

use crate::status::JobState;

/// The states a job ends in: it will not change any more (`succeeded`, `failed`, `cancelled`).
pub const ENDED: [JobState; 3] = [JobState::Succeeded, JobState::Failed, JobState::Cancelled];

/// The states of a job that has not ended: waiting, on a worker, or parked.
pub const ACTIVE: [JobState; 3] = [JobState::Queued, JobState::Running, JobState::Paused];

/// A change of a job's state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Transition {
    /// A new job is accepted: it waits for a worker (an extension is inserted paused, then
    /// resumed once it is linked to the job it continues).
    Submit,
    /// A worker takes a queued job: the local queue's start, or a claim from the shared queue.
    Claim,
    /// A worker of the shared queue takes a job whose replica stopped renewing its lease (the
    /// job stays running, under the new replica).
    Takeover,
    /// A run is over: its result (or its error, or the cancel) is stored.
    End,
    /// A queued job is cancelled before any worker took it.
    CancelQueued,
    /// A queued job is parked at once, a running one after the checkpoint of its next step.
    Pause,
    /// A paused job is queued again.
    Resume,
    /// A paused job is cancelled (its checkpoint and rows dropped).
    CancelPaused,
    /// A running job goes back to the queue: its server shut down (a shared queue gives it back
    /// at once, SQLite at the next start).
    Release,
    /// A study's parent (running from its submission) is completed with its report, fails, or
    /// is cancelled.
    EndStudy,
}

impl Transition {
    /// Every transition.
    pub const ALL: [Transition; 10] = [
        Transition::Submit,
        Transition::Claim,
        Transition::Takeover,
        Transition::End,
        Transition::CancelQueued,
        Transition::Pause,
        Transition::Resume,
        Transition::CancelPaused,
        Transition::Release,
        Transition::EndStudy,
    ];

    /// The states this transition is legal from (empty for [`Transition::Submit`]: the job
    /// does not exist before).
    pub const fn from(self) -> &'static [JobState] {
        match self {
            Transition::Submit => &[],
            Transition::Claim | Transition::CancelQueued => &[JobState::Queued],
            Transition::Takeover | Transition::End | Transition::Release => &[JobState::Running],
            Transition::EndStudy => &[JobState::Running],
            Transition::Pause => &[JobState::Queued, JobState::Running],
            Transition::Resume | Transition::CancelPaused => &[JobState::Paused],
        }
    }

    /// The states this transition leads to.
    pub const fn to(self) -> &'static [JobState] {
        match self {
            Transition::Submit => &[JobState::Queued, JobState::Paused],
            Transition::Claim | Transition::Takeover => &[JobState::Running],
            Transition::End | Transition::EndStudy => &ENDED,
            Transition::CancelQueued | Transition::CancelPaused => &[JobState::Cancelled],
            Transition::Pause => &[JobState::Paused],
            Transition::Resume | Transition::Release => &[JobState::Queued],
        }
    }

    /// True when the transition may take a job in state `from` to state `to`.
    pub fn allows(self, from: JobState, to: JobState) -> bool {
        self.from().contains(&from) && self.to().contains(&to)
    }

    /// The SQL condition that a job's `state` column is one this transition leaves from:
    /// `state = 'queued'`, `state IN ('queued', 'running')`.
    pub fn from_sql(self) -> String {
        states_sql("state", self.from())
    }

    /// The SQL literal of the one state this transition leads to (`'paused'`), for `SET state
    /// = …`.
    ///
    /// # Panics
    /// For a transition to several states ([`Transition::End`], [`Transition::EndStudy`],
    /// [`Transition::Submit`]), whose state is a statement parameter: a bug, found by the
    /// stores' tests the first time the statement is built.
    pub fn to_sql(self) -> String {
        match self.to() {
            [one] => literal(*one),
            many => panic!("{self:?} leads to {many:?}: its state is a parameter"),
        }
    }

    /// The statement that makes this change to the rows of `jobs` that `filter` selects and
    /// that are in a state it leaves from, also setting `set` (columns, or empty):
    /// `UPDATE jobs SET state = 'paused', done = ?2 WHERE id = ?1 AND state IN ('queued',
    /// 'running')`. For a transition to one state ([`Transition::to_sql`]).
    pub fn update_sql(self, set: &str, filter: &str) -> String {
        let set = if set.is_empty() {
            String::new()
        } else {
            format!(", {set}")
        };
        format!(
            "UPDATE jobs SET state = {}{set} WHERE {filter} AND {}",
            self.to_sql(),
            self.from_sql()
        )
    }
}

/// The count of jobs in every state, in [`JobState::ALL`]'s order, from the `(state, count)`
/// rows a store's `GROUP BY state` gave (a state without a row counts 0).
pub fn per_state(rows: &[(String, u64)]) -> Vec<(JobState, u64)> {
    JobState::ALL
        .into_iter()
        .map(|s| {
            let n = rows.iter().find(|(name, _)| name == s.as_str());
            (s, n.map_or(0, |(_, c)| *c))
        })
        .collect()
}

/// The SQL literal of a state: `'queued'`.
pub fn literal(state: JobState) -> String {
    format!("'{}'", state.as_str())
}

/// The SQL list of states: `('succeeded', 'failed', 'cancelled')`.
pub fn in_sql(states: &[JobState]) -> String {
    let names: Vec<String> = states.iter().map(|&s| literal(s)).collect();
    format!("({})", names.join(", "))
}

/// The SQL condition that column `column` holds `state`: `state = 'running'`.
pub fn is_sql(column: &str, state: JobState) -> String {
    format!("{column} = {}", literal(state))
}

/// The SQL condition that column `column` holds one of `states` (`=` for one, `IN` for more).
fn states_sql(column: &str, states: &[JobState]) -> String {
    match states {
        [one] => is_sql(column, *one),
        many => format!("{column} IN {}", in_sql(many)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_transition_leaves_an_ended_state() {
        for t in Transition::ALL {
            for s in ENDED {
                assert!(!t.from().contains(&s), "{t:?} leaves {s:?}");
            }
        }
    }

    #[test]
    fn ended_and_active_split_every_state() {
        for s in JobState::ALL {
            assert_eq!(ENDED.contains(&s), !ACTIVE.contains(&s), "{s:?}");
            assert_eq!(ENDED.contains(&s), s.is_terminal(), "{s:?}");
        }
    }

    #[test]
    fn every_state_is_reached_and_every_active_one_left() {
        for s in JobState::ALL {
            assert!(
                Transition::ALL.iter().any(|t| t.to().contains(&s)),
                "{s:?} is never reached"
            );
        }
        for s in ACTIVE {
            assert!(
                Transition::ALL
                    .iter()
                    .any(|t| t.from().contains(&s) && !t.to().contains(&s)),
                "{s:?} is never left"
            );
        }
    }

    #[test]
    fn the_table_answers_for_the_lifecycle() {
        assert!(Transition::Pause.allows(JobState::Running, JobState::Paused));
        assert!(Transition::Pause.allows(JobState::Queued, JobState::Paused));
        assert!(!Transition::Pause.allows(JobState::Paused, JobState::Paused));
        assert!(Transition::End.allows(JobState::Running, JobState::Failed));
        assert!(!Transition::End.allows(JobState::Queued, JobState::Succeeded));
        assert!(!Transition::Resume.allows(JobState::Cancelled, JobState::Queued));
        assert!(Transition::Takeover.allows(JobState::Running, JobState::Running));
    }

    #[test]
    fn sql_is_built_from_the_table() {
        assert_eq!(in_sql(&ENDED), "('succeeded', 'failed', 'cancelled')");
        assert_eq!(
            Transition::Pause.from_sql(),
            "state IN ('queued', 'running')"
        );
        assert_eq!(Transition::Resume.from_sql(), "state = 'paused'");
        assert_eq!(Transition::Resume.to_sql(), "'queued'");
        assert_eq!(Transition::CancelQueued.to_sql(), "'cancelled'");
        assert_eq!(is_sql("c.state", JobState::Running), "c.state = 'running'");
        assert_eq!(
            Transition::Resume.update_sql("", "id = ?1"),
            "UPDATE jobs SET state = 'queued' WHERE id = ?1 AND state = 'paused'"
        );
        assert_eq!(
            Transition::Pause.update_sql("done = $2", "id = $1"),
            "UPDATE jobs SET state = 'paused', done = $2 WHERE id = $1 AND state IN ('queued', 'running')"
        );
    }

    #[test]
    fn counts_cover_every_state() {
        let rows = [("running".to_string(), 2), ("failed".to_string(), 5)];
        let counts = per_state(&rows);
        assert_eq!(counts.len(), 6);
        assert_eq!(counts[0], (JobState::Queued, 0));
        assert_eq!(counts[1], (JobState::Running, 2));
        assert_eq!(counts[3], (JobState::Failed, 5));
    }

    #[test]
    #[should_panic(expected = "its state is a parameter")]
    fn an_end_has_no_single_state() {
        let _ = Transition::End.to_sql();
    }
}
