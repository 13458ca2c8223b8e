//! [`PauseStore`] for the SQLite store: tables `final_states (id, step, bytes)` (the checkpoint
//! a succeeded job kept after its last step) and `extensions (id, extends)`.

use super::{JOB_COLUMNS, SqliteStore, finish_row, row_to_job};
use crate::lifecycle::Transition;
use crate::status::JobView;
use crate::store::StoreError;
use crate::store::pause::PauseStore;
use rusqlite::{Connection, OptionalExtension, params};

/// The tables of this module (created if missing: a store of an older build gets them).
pub(super) fn create_tables(conn: &Connection) -> Result<(), StoreError> {
    conn.execute_batch(
        "CREATE TABLE IF NOT EXISTS final_states (
            id TEXT PRIMARY KEY,
            step INTEGER NOT NULL,
            bytes BLOB NOT NULL
        );
        CREATE TABLE IF NOT EXISTS extensions (
            id TEXT PRIMARY KEY,
            extends TEXT NOT NULL
        );",
    )?;
    Ok(())
}

/// Forgets what this module keeps of job `id` (the job is being removed).
pub(super) fn delete_job(tx: &Connection, id: &str) -> Result<(), StoreError> {
    tx.execute("DELETE FROM final_states WHERE id = ?1", [id])?;
    tx.execute("DELETE FROM extensions WHERE id = ?1", [id])?;
    Ok(())
}

impl SqliteStore {
    /// A job's status and spec.
    fn job_with_spec(conn: &Connection, id: &str) -> Result<Option<(JobView, String)>, StoreError> {
        conn.query_row(
            &format!("SELECT {JOB_COLUMNS} FROM jobs WHERE id = ?1"),
            [id],
            row_to_job,
        )
        .optional()?
        .map(finish_row)
        .transpose()
    }
}

impl PauseStore for SqliteStore {
    fn park(&self, row: &JobView) -> Result<bool, StoreError> {
        let n = self.conn().execute(
            &Transition::Pause.update_sql("done = ?2, total = ?3, t = ?4", "id = ?1"),
            params![row.id, row.done as i64, row.total as i64, row.t],
        )?;
        Ok(n == 1)
    }

    fn unpark(&self, id: &str) -> Result<Option<(JobView, String)>, StoreError> {
        let mut conn = self.conn();
        let tx = conn.transaction()?;
        let n = tx.execute(&Transition::Resume.update_sql("", "id = ?1"), [id])?;
        if n == 0 {
            return Ok(None);
        }
        let job = Self::job_with_spec(&tx, id)?;
        tx.commit()?;
        Ok(job)
    }

    fn cancel_parked(&self, id: &str, finished_ms: u64) -> Result<Option<JobView>, StoreError> {
        let mut conn = self.conn();
        let tx = conn.transaction()?;
        let n = tx.execute(
            &Transition::CancelPaused.update_sql("finished_ms = ?2", "id = ?1"),
            params![id, finished_ms as i64],
        )?;
        if n == 0 {
            return Ok(None);
        }
        tx.execute("DELETE FROM checkpoints WHERE id = ?1", [id])?;
        tx.execute("DELETE FROM result_chunks WHERE id = ?1", [id])?;
        let job = Self::job_with_spec(&tx, id)?.map(|(view, _)| view);
        tx.commit()?;
        Ok(job)
    }

    fn keep_final_state(&self, id: &str, step: u64) -> Result<bool, StoreError> {
        let n = self.conn().execute(
            "INSERT OR REPLACE INTO final_states (id, step, bytes)
             SELECT id, step, bytes FROM checkpoints WHERE id = ?1 AND step = ?2",
            params![id, step as i64],
        )?;
        Ok(n == 1)
    }

    fn final_state(&self, id: &str) -> Result<Option<(u64, Vec<u8>)>, StoreError> {
        Ok(self
            .conn()
            .query_row(
                "SELECT step, bytes FROM final_states WHERE id = ?1",
                [id],
                |r| Ok((r.get::<_, i64>(0)? as u64, r.get::<_, Vec<u8>>(1)?)),
            )
            .optional()?)
    }

    fn link_extension(&self, from: &str, to: &str) -> Result<bool, StoreError> {
        let mut conn = self.conn();
        let tx = conn.transaction()?;
        let n = tx.execute(
            "INSERT OR REPLACE INTO checkpoints (id, attempt, step, bytes)
             SELECT ?2, 0, step, bytes FROM final_states WHERE id = ?1",
            params![from, to],
        )?;
        if n == 0 {
            return Ok(false);
        }
        tx.execute(
            "INSERT OR REPLACE INTO extensions (id, extends) VALUES (?1, ?2)",
            params![to, from],
        )?;
        tx.commit()?;
        Ok(true)
    }

    fn extends(&self, id: &str) -> Result<Option<String>, StoreError> {
        Ok(self
            .conn()
            .query_row("SELECT extends FROM extensions WHERE id = ?1", [id], |r| {
                r.get::<_, String>(0)
            })
            .optional()?)
    }

    fn spec_json(&self, id: &str) -> Result<Option<String>, StoreError> {
        Ok(Self::job_with_spec(&self.conn(), id)?.map(|(_, spec)| spec))
    }
}
