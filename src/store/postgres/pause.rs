//! [`PauseStore`] for the PostgreSQL store (migration `0004_pause`): the `paused` state, the
//! `pause_requested` flag a replica running the job reads at its heartbeat, `final_states` and
//! `extensions`. Every change of state is one conditional statement, so two replicas (or a
//! pause racing a cancel) never both win.

use super::{CHANNEL, JOB_COLUMNS, PgStore, ask_running, pg, view};
use crate::lifecycle::{Transition, is_sql};
use crate::status::{JobState, JobView};
use crate::store::StoreError;
use crate::store::pause::PauseStore;

impl PauseStore for PgStore {
    fn park(&self, row: &JobView) -> Result<bool, StoreError> {
        let (id, owner) = (row.id.clone(), self.replica.clone());
        let (done, total, t) = (row.done as i64, row.total as i64, row.t);
        self.with(move |c| async move {
            let n = c
                .execute(
                    &c.prepare_cached(&Transition::Pause.update_sql(
                        "done = $2, total = $3, t = $4, owner = NULL, lease_until = NULL, pause_requested = FALSE",
                        &format!("id = $1 AND ({} OR owner = $5)", is_sql("state", JobState::Queued)),
                    ))
                    .await
                    .map_err(pg)?,
                    &[&id, &done, &total, &t, &owner],
                )
                .await
                .map_err(pg)?;
            Ok(n == 1)
        })
    }

    fn unpark(&self, id: &str) -> Result<Option<(JobView, String)>, StoreError> {
        let id = id.to_string();
        self.with(move |c| async move {
            // Queued and announced in one statement: the notification goes at commit.
            let row = c
                .query_opt(
                    &c.prepare_cached(&format!(
                        "WITH up AS ({} RETURNING {JOB_COLUMNS}, spec_json)
                         SELECT up.*, pg_notify('{CHANNEL}', up.id) FROM up",
                        Transition::Resume
                            .update_sql("started_ms = 0, pause_requested = FALSE", "id = $1"),
                    ))
                    .await
                    .map_err(pg)?,
                    &[&id],
                )
                .await
                .map_err(pg)?;
            row.map(|r| Ok((view(&r)?, r.try_get::<_, String>(11).map_err(pg)?)))
                .transpose()
        })
    }

    fn cancel_parked(&self, id: &str, finished_ms: u64) -> Result<Option<JobView>, StoreError> {
        let id = id.to_string();
        self.with(move |mut c| async move {
            let tx = c.transaction().await.map_err(pg)?;
            let row = tx
                .query_opt(
                    &format!(
                        "{} RETURNING {JOB_COLUMNS}",
                        Transition::CancelPaused
                            .update_sql("finished_ms = $2, pause_requested = FALSE", "id = $1"),
                    ),
                    &[&id, &(finished_ms as i64)],
                )
                .await
                .map_err(pg)?;
            let Some(row) = row else {
                return Ok(None);
            };
            tx.execute("DELETE FROM checkpoints WHERE id = $1", &[&id])
                .await
                .map_err(pg)?;
            tx.execute("DELETE FROM result_chunks WHERE id = $1", &[&id])
                .await
                .map_err(pg)?;
            tx.commit().await.map_err(pg)?;
            Ok(Some(view(&row)?))
        })
    }

    fn request_pause(&self, id: &str) -> Result<bool, StoreError> {
        let id = id.to_string();
        self.with(move |c| async move { ask_running(&c, "pause_requested", &id).await })
    }

    fn keep_final_state(&self, id: &str, step: u64) -> Result<bool, StoreError> {
        let id = id.to_string();
        self.with(move |c| async move {
            let n = c
                .execute(
                    &c.prepare_cached(
                        "INSERT INTO final_states (id, step, bytes)
                         SELECT id, step, bytes FROM checkpoints WHERE id = $1 AND step = $2
                         ON CONFLICT (id) DO UPDATE SET step = EXCLUDED.step, bytes = EXCLUDED.bytes",
                    )
                    .await
                    .map_err(pg)?,
                    &[&id, &(step as i64)],
                )
                .await
                .map_err(pg)?;
            Ok(n == 1)
        })
    }

    fn final_state(&self, id: &str) -> Result<Option<(u64, Vec<u8>)>, StoreError> {
        let id = id.to_string();
        self.with(move |c| async move {
            let row = c
                .query_opt(
                    &c.prepare_cached("SELECT step, bytes FROM final_states WHERE id = $1")
                        .await
                        .map_err(pg)?,
                    &[&id],
                )
                .await
                .map_err(pg)?;
            row.map(|r| {
                Ok((
                    r.try_get::<_, i64>(0).map_err(pg)? as u64,
                    r.try_get::<_, Vec<u8>>(1).map_err(pg)?,
                ))
            })
            .transpose()
        })
    }

    fn link_extension(&self, from: &str, to: &str) -> Result<bool, StoreError> {
        let (from, to) = (from.to_string(), to.to_string());
        self.with(move |mut c| async move {
            let tx = c.transaction().await.map_err(pg)?;
            let n = tx
                .execute(
                    "INSERT INTO checkpoints (id, attempt, step, bytes)
                     SELECT $2, 0, step, bytes FROM final_states WHERE id = $1
                     ON CONFLICT (id) DO UPDATE SET attempt = 0, step = EXCLUDED.step, bytes = EXCLUDED.bytes",
                    &[&from, &to],
                )
                .await
                .map_err(pg)?;
            if n == 0 {
                return Ok(false);
            }
            tx.execute(
                "INSERT INTO extensions (id, extends) VALUES ($1, $2)
                 ON CONFLICT (id) DO UPDATE SET extends = EXCLUDED.extends",
                &[&to, &from],
            )
            .await
            .map_err(pg)?;
            tx.commit().await.map_err(pg)?;
            Ok(true)
        })
    }

    fn extends(&self, id: &str) -> Result<Option<String>, StoreError> {
        self.text_of("SELECT extends FROM extensions WHERE id = $1", id)
    }

    fn spec_json(&self, id: &str) -> Result<Option<String>, StoreError> {
        self.text_of("SELECT spec_json FROM jobs WHERE id = $1", id)
    }
}

impl PgStore {
    /// The text in the first column of the row `sql` selects for `id`, if any.
    pub(super) fn text_of(
        &self,
        sql: &'static str,
        id: &str,
    ) -> Result<Option<String>, StoreError> {
        let id = id.to_string();
        self.with(move |c| async move {
            let row = c
                .query_opt(&c.prepare_cached(sql).await.map_err(pg)?, &[&id])
                .await
                .map_err(pg)?;
            row.map(|r| r.try_get::<_, String>(0).map_err(pg))
                .transpose()
        })
    }
}
