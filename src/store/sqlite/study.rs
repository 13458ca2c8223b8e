//! [`StudyStore`] on SQLite: columns `jobs.parent` and `jobs.children`, added to a database of
//! an earlier schema by [`migrate`].

use super::{JOB_COLUMNS, SqliteStore, finish_row, row_to_job};
use crate::lifecycle::{ENDED, Transition, in_sql};
use crate::status::JobView;
use crate::store::{ResultTexts, StoreError, StoredResult, StudyStore};
use rusqlite::{Connection, OptionalExtension, params};

/// Adds `jobs.parent` (a child's parent job) and `jobs.children` (a parent's number of
/// children; 0 for every other job) when missing.
pub(super) fn migrate(conn: &Connection) -> Result<(), StoreError> {
    let have: Vec<String> = conn
        .prepare("SELECT name FROM pragma_table_info('jobs')")?
        .query_map([], |r| r.get::<_, String>(0))?
        .collect::<Result<Vec<_>, _>>()?;
    if !have.iter().any(|c| c == "parent") {
        conn.execute_batch("ALTER TABLE jobs ADD COLUMN parent TEXT")?;
    }
    if !have.iter().any(|c| c == "children") {
        conn.execute_batch("ALTER TABLE jobs ADD COLUMN children INTEGER NOT NULL DEFAULT 0")?;
    }
    conn.execute_batch("CREATE INDEX IF NOT EXISTS jobs_parent ON jobs (parent, seq)")?;
    Ok(())
}

impl StudyStore for SqliteStore {
    fn insert_study(
        &self,
        parent: &JobView,
        spec_json: &str,
        children: &[(JobView, String)],
    ) -> Result<bool, StoreError> {
        let mut conn = self.conn();
        let tx = conn.transaction()?;
        let n = tx.execute(
            "INSERT OR IGNORE INTO jobs (id, name, spec_json, state, created_ms, started_ms, total, children)
             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?7)",
            params![
                parent.id,
                parent.name,
                spec_json,
                parent.state.as_str(),
                parent.created_ms as i64,
                parent.started_ms as i64,
                children.len() as i64
            ],
        )?;
        if n != 1 {
            return Ok(false);
        }
        for (row, spec) in children {
            let n = tx.execute(
                "INSERT OR IGNORE INTO jobs (id, name, spec_json, state, created_ms, total, parent)
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)",
                params![
                    row.id,
                    row.name,
                    spec,
                    row.state.as_str(),
                    row.created_ms as i64,
                    row.total as i64,
                    parent.id
                ],
            )?;
            if n != 1 {
                return Ok(false);
            }
        }
        tx.commit()?;
        Ok(true)
    }

    fn is_study(&self, id: &str) -> Result<bool, StoreError> {
        let n: Option<i64> = self
            .conn()
            .query_row("SELECT children FROM jobs WHERE id = ?1", [id], |r| {
                r.get(0)
            })
            .optional()?;
        Ok(n.is_some_and(|n| n > 0))
    }

    fn study_spec(&self, id: &str) -> Result<Option<String>, StoreError> {
        Ok(self
            .conn()
            .query_row(
                "SELECT spec_json FROM jobs WHERE id = ?1 AND children > 0",
                [id],
                |r| r.get(0),
            )
            .optional()?)
    }

    fn children(&self, parent: &str) -> Result<Vec<JobView>, StoreError> {
        let conn = self.conn();
        let mut stmt = conn.prepare(&format!(
            "SELECT {JOB_COLUMNS} FROM jobs WHERE parent = ?1 ORDER BY seq"
        ))?;
        let rows = stmt
            .query_map([parent], row_to_job)?
            .collect::<Result<Vec<_>, _>>()?;
        rows.into_iter().map(|row| Ok(finish_row(row)?.0)).collect()
    }

    fn child_ended(&self, id: &str) -> Result<Option<JobView>, StoreError> {
        let conn = self.conn();
        let parent: Option<String> = conn
            .query_row("SELECT parent FROM jobs WHERE id = ?1", [id], |r| r.get(0))
            .optional()?
            .flatten();
        let Some(parent) = parent else {
            return Ok(None);
        };
        let n = conn.execute(
            &format!(
                "UPDATE jobs SET done = (SELECT COUNT(*) FROM jobs c WHERE c.parent = ?1 AND c.state IN {})
                 WHERE id = ?1 AND {} AND children > 0",
                in_sql(&ENDED),
                Transition::EndStudy.from_sql()
            ),
            [&parent],
        )?;
        if n == 0 {
            return Ok(None);
        }
        let row = conn
            .query_row(
                &format!("SELECT {JOB_COLUMNS} FROM jobs WHERE id = ?1"),
                [&parent],
                row_to_job,
            )
            .optional()?;
        Ok(row.map(finish_row).transpose()?.map(|(view, _)| view))
    }

    fn finish_study(
        &self,
        row: &JobView,
        result: Option<&StoredResult>,
    ) -> Result<bool, StoreError> {
        let mut conn = self.conn();
        let tx = conn.transaction()?;
        let (field, reason) = row.error_parts();
        let n = tx.execute(
            &format!(
                "UPDATE jobs SET state = ?2, finished_ms = ?3, error_field = ?4, error_reason = ?5, done = ?6, total = ?7, t = ?8
                 WHERE id = ?1 AND {} AND children > 0",
                Transition::EndStudy.from_sql()
            ),
            params![
                row.id,
                row.state.as_str(),
                row.finished_ms as i64,
                field,
                reason,
                row.done as i64,
                row.total as i64,
                row.t
            ],
        )?;
        if n == 0 {
            return Ok(false);
        }
        if let Some(r) = result {
            let texts = ResultTexts::of(r);
            tx.execute(
                "INSERT OR REPLACE INTO results (id, summary_json, columns_json, steps, t, vals, tables_json, figures_json, partial)
                 VALUES (?1, ?2, ?3, x'', x'', x'', ?4, ?5, ?6)",
                params![
                    row.id,
                    texts.summary,
                    texts.columns,
                    texts.tables,
                    texts.figures,
                    r.partial
                ],
            )?;
        }
        tx.commit()?;
        Ok(true)
    }

    fn studies_to_finish(&self) -> Result<Vec<String>, StoreError> {
        let conn = self.conn();
        let mut stmt = conn.prepare(&format!(
            "SELECT p.id FROM jobs p WHERE p.children > 0 AND p.{}
             AND NOT EXISTS (SELECT 1 FROM jobs c WHERE c.parent = p.id AND c.state NOT IN {})
             ORDER BY p.seq",
            Transition::EndStudy.from_sql(),
            in_sql(&ENDED)
        ))?;
        let ids = stmt
            .query_map([], |r| r.get::<_, String>(0))?
            .collect::<Result<Vec<_>, _>>()?;
        Ok(ids)
    }
}
