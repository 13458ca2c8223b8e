//! [`StudyStore`] on PostgreSQL (migration `0003_studies`): any replica may record, progress,
//! complete or cancel a study; completing is one conditional update, so of two replicas that
//! see the last child end, one writes the report.

use super::{CHANNEL, JOB_COLUMNS, PgStore, pg, view};
use crate::lifecycle::{ENDED, Transition, in_sql};
use crate::status::JobView;
use crate::store::{ResultTexts, StoreError, StoredResult, StudyStore};

impl StudyStore for PgStore {
    fn insert_study(
        &self,
        parent: &JobView,
        spec_json: &str,
        children: &[(JobView, String)],
    ) -> Result<bool, StoreError> {
        let parent = parent.clone();
        let spec = spec_json.to_string();
        let children = children.to_vec();
        self.with(move |mut c| async move {
            let tx = c.transaction().await.map_err(pg)?;
            let n = tx
                .execute(
                    "INSERT INTO jobs (id, name, spec_json, state, created_ms, started_ms, total, children)
                     VALUES ($1, $2, $3, $4, $5, $6, $7, $7) ON CONFLICT (id) DO NOTHING",
                    &[
                        &parent.id,
                        &parent.name,
                        &spec,
                        &parent.state.as_str(),
                        &(parent.created_ms as i64),
                        &(parent.started_ms as i64),
                        &(children.len() as i64),
                    ],
                )
                .await
                .map_err(pg)?;
            if n != 1 {
                return Ok(false);
            }
            // Each child is announced at commit, as a job of its own.
            let st = tx
                .prepare(&format!(
                    "WITH ins AS (
                        INSERT INTO jobs (id, name, spec_json, state, created_ms, total, parent)
                        VALUES ($1, $2, $3, $4, $5, $6, $7) ON CONFLICT (id) DO NOTHING RETURNING id)
                     SELECT pg_notify('{CHANNEL}', id) FROM ins"
                ))
                .await
                .map_err(pg)?;
            for (row, spec) in &children {
                let n = tx
                    .query(
                        &st,
                        &[
                            &row.id,
                            &row.name,
                            spec,
                            &row.state.as_str(),
                            &(row.created_ms as i64),
                            &(row.total as i64),
                            &parent.id,
                        ],
                    )
                    .await
                    .map_err(pg)?
                    .len();
                if n != 1 {
                    return Ok(false);
                }
            }
            tx.commit().await.map_err(pg)?;
            Ok(true)
        })
    }

    fn is_study(&self, id: &str) -> Result<bool, StoreError> {
        let id = id.to_string();
        self.with(move |c| async move {
            let r = c
                .query_opt(
                    &c.prepare_cached("SELECT children FROM jobs WHERE id = $1")
                        .await
                        .map_err(pg)?,
                    &[&id],
                )
                .await
                .map_err(pg)?;
            Ok(match r {
                Some(r) => r.try_get::<_, i64>(0).map_err(pg)? > 0,
                None => false,
            })
        })
    }

    fn study_spec(&self, id: &str) -> Result<Option<String>, StoreError> {
        self.text_of(
            "SELECT spec_json FROM jobs WHERE id = $1 AND children > 0",
            id,
        )
    }

    fn children(&self, parent: &str) -> Result<Vec<JobView>, StoreError> {
        let parent = parent.to_string();
        self.with(move |c| async move {
            c.query(
                &c.prepare_cached(&format!(
                    "SELECT {JOB_COLUMNS} FROM jobs WHERE parent = $1 ORDER BY seq"
                ))
                .await
                .map_err(pg)?,
                &[&parent],
            )
            .await
            .map_err(pg)?
            .iter()
            .map(view)
            .collect()
        })
    }

    fn child_ended(&self, id: &str) -> Result<Option<JobView>, StoreError> {
        let id = id.to_string();
        let columns = JOB_COLUMNS
            .split(", ")
            .map(|c| format!("p.{c}"))
            .collect::<Vec<_>>()
            .join(", ");
        self.with(move |c| async move {
            // One statement, so a job that is no child costs one round trip. GREATEST: of two
            // replicas ending children at once, a count from an older snapshot never lowers it.
            c.query_opt(
                &c.prepare_cached(&format!(
                    "UPDATE jobs p SET done = GREATEST(p.done,
                            (SELECT COUNT(*) FROM jobs c WHERE c.parent = p.id AND c.state IN {}))
                     FROM jobs k WHERE k.id = $1 AND p.id = k.parent AND p.{} AND p.children > 0
                     RETURNING {columns}",
                    in_sql(&ENDED),
                    Transition::EndStudy.from_sql(),
                ))
                .await
                .map_err(pg)?,
                &[&id],
            )
            .await
            .map_err(pg)?
            .map(|r| view(&r))
            .transpose()
        })
    }

    fn finish_study(
        &self,
        row: &JobView,
        result: Option<&StoredResult>,
    ) -> Result<bool, StoreError> {
        let row = row.clone();
        let texts = result.map(ResultTexts::of);
        self.with(move |c| async move {
            let (field, reason) = row.error_parts();
            let has_result = texts.is_some();
            let texts = texts.unwrap_or_default();
            let done = c
                .query_opt(
                    &c.prepare_cached(&format!(
                        "WITH done AS (
                            UPDATE jobs SET state = $2, finished_ms = $3, error_field = $4, error_reason = $5,
                                   done = $6, total = $7, t = $8
                            WHERE id = $1 AND {} AND children > 0 RETURNING attempt),
                         ins AS (
                            INSERT INTO results (id, attempt, summary_json, columns_json, tables_json, figures_json, partial)
                            SELECT $1, attempt, $9, $10, $11, $12, FALSE FROM done WHERE $13
                            ON CONFLICT (id, attempt) DO NOTHING)
                         SELECT attempt FROM done",
                        Transition::EndStudy.from_sql(),
                    ))
                    .await
                    .map_err(pg)?,
                    &[
                        &row.id,
                        &row.state.as_str(),
                        &(row.finished_ms as i64),
                        &field,
                        &reason,
                        &(row.done as i64),
                        &(row.total as i64),
                        &row.t,
                        &texts.summary,
                        &texts.columns,
                        &texts.tables,
                        &texts.figures,
                        &has_result,
                    ],
                )
                .await
                .map_err(pg)?;
            Ok(done.is_some())
        })
    }

    fn studies_to_finish(&self) -> Result<Vec<String>, StoreError> {
        self.with(move |c| async move {
            c.query(
                &c.prepare_cached(&format!(
                    "SELECT p.id FROM jobs p WHERE p.children > 0 AND p.{}
                     AND NOT EXISTS (SELECT 1 FROM jobs c WHERE c.parent = p.id AND c.state NOT IN {})
                     ORDER BY p.seq",
                    Transition::EndStudy.from_sql(),
                    in_sql(&ENDED),
                ))
                .await
                .map_err(pg)?,
                &[],
            )
            .await
            .map_err(pg)?
            .iter()
            .map(|r| r.try_get(0).map_err(pg))
            .collect()
        })
    }
}
