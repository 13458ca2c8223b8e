//! The result store: one embedded SQLite file (WAL) with every job's spec, status, summary and
//! recorded series.
//!
//! A job's row is written when it is accepted, updated when it starts, and completed in one
//! transaction with its result, so a crash (SIGKILL) leaves every finished result whole and every
//! unfinished job marked `queued` or `running`; [`Store::recover`] turns the latter back into
//! `queued` at start-up. Series are stored as little-endian f64 blobs: what is read back is what
//! was computed, bit for bit. Figures (SVG text) are kept as a JSON list in `figures_json`; a
//! database made before that column existed gets it (empty lists) when it is opened.

use crate::status::{JobState, JobView};
use rusqlite::{Connection, OptionalExtension, params};
use serde_json::{Map, Value};
use signorini_core::outcome::Table;
use signorini_core::spec::SpecError;
use signorini_figures::Figure;
use std::path::Path;
use std::sync::Mutex;
use thiserror::Error;

/// A store failure.
#[derive(Debug, Error)]
pub enum StoreError {
    /// SQLite said no.
    #[error("store: {0}")]
    Sql(#[from] rusqlite::Error),
    /// A stored value does not decode.
    #[error("store: corrupt {what} of job {id}")]
    Corrupt {
        /// Which column.
        what: &'static str,
        /// Which job.
        id: String,
    },
}

/// A finished job's result.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StoredResult {
    /// summary.json.
    pub summary: Map<String, Value>,
    /// Columns besides `step` and `t`.
    pub columns: Vec<String>,
    /// Step numbers of the records.
    pub steps: Vec<u64>,
    /// Times of the records.
    pub t: Vec<f64>,
    /// Values, row-major (`values[i * columns.len() + c]`).
    pub values: Vec<f64>,
    /// Extra tables (analyses).
    pub tables: Vec<Table>,
    /// Figures (SVG text), in the order the job made them.
    pub figures: Vec<Figure>,
}

impl StoredResult {
    /// The figure called `name` (`NAME` or `NAME.svg`), if the job made one.
    pub fn figure(&self, name: &str) -> Option<&Figure> {
        let stem = name.strip_suffix(".svg").unwrap_or(name);
        let by = |n: &str| self.figures.iter().find(|f| f.name == n);
        by(name).or_else(|| by(stem))
    }

    /// The series cut down to `columns` (all when empty, in the stored order otherwise as
    /// asked) and to every `every`-th record plus the last (all when `every` ≤ 1). Values are
    /// copied, never recomputed: what is left is bit-identical to the stored result.
    pub fn select(mut self, columns: &[String], every: u64) -> Result<Self, SpecError> {
        let at: Vec<usize> = if columns.is_empty() {
            (0..self.columns.len()).collect()
        } else {
            columns
                .iter()
                .map(|name| {
                    self.columns.iter().position(|c| c == name).ok_or_else(|| {
                        SpecError::new(
                            "columns",
                            format!(
                                "no column {name:?} (the result has {})",
                                self.columns.join(", ")
                            ),
                        )
                    })
                })
                .collect::<Result<_, _>>()?
        };
        let n = self.columns.len();
        let rows = self.steps.len();
        let every = every.max(1) as usize;
        let keep: Vec<usize> = (0..rows)
            .filter(|&i| i % every == 0 || i + 1 == rows)
            .collect();
        let mut values = Vec::with_capacity(keep.len() * at.len());
        for &i in &keep {
            values.extend(at.iter().map(|&c| self.values[i * n + c]));
        }
        self.columns = at.iter().map(|&c| self.columns[c].clone()).collect();
        self.steps = keep.iter().map(|&i| self.steps[i]).collect();
        self.t = keep.iter().map(|&i| self.t[i]).collect();
        self.values = values;
        Ok(self)
    }

    /// The values of column `c`.
    pub fn column(&self, c: usize) -> Vec<f64> {
        let n = self.columns.len();
        self.values
            .iter()
            .skip(c)
            .step_by(n.max(1))
            .copied()
            .collect()
    }
}

/// The SQLite store (one connection behind a mutex: calls are short).
pub struct Store {
    conn: Mutex<Connection>,
}

const SCHEMA: &str = "
CREATE TABLE IF NOT EXISTS jobs (
    seq INTEGER PRIMARY KEY AUTOINCREMENT,
    id TEXT NOT NULL UNIQUE,
    name TEXT,
    spec_json TEXT NOT NULL,
    state TEXT NOT NULL,
    created_ms INTEGER NOT NULL,
    started_ms INTEGER NOT NULL DEFAULT 0,
    finished_ms INTEGER NOT NULL DEFAULT 0,
    error_field TEXT,
    error_reason TEXT,
    done INTEGER NOT NULL DEFAULT 0,
    total INTEGER NOT NULL DEFAULT 0,
    t REAL NOT NULL DEFAULT 0
);
CREATE TABLE IF NOT EXISTS results (
    id TEXT PRIMARY KEY REFERENCES jobs(id),
    summary_json TEXT NOT NULL,
    columns_json TEXT NOT NULL,
    steps BLOB NOT NULL,
    t BLOB NOT NULL,
    vals BLOB NOT NULL,
    tables_json TEXT NOT NULL,
    figures_json TEXT NOT NULL DEFAULT '[]'
);
";

/// Brings a database made by an older schema up to [`SCHEMA`]: `results.figures_json` came later.
fn migrate(conn: &Connection) -> Result<(), StoreError> {
    let has_figures = conn
        .prepare("SELECT name FROM pragma_table_info('results')")?
        .query_map([], |r| r.get::<_, String>(0))?
        .collect::<Result<Vec<_>, _>>()?
        .iter()
        .any(|c| c == "figures_json");
    if !has_figures {
        conn.execute_batch(
            "ALTER TABLE results ADD COLUMN figures_json TEXT NOT NULL DEFAULT '[]'",
        )?;
    }
    Ok(())
}

fn f64s_to_blob(v: &[f64]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn u64s_to_blob(v: &[u64]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn blob_to_8(b: &[u8]) -> Option<impl Iterator<Item = [u8; 8]> + '_> {
    if !b.len().is_multiple_of(8) {
        return None;
    }
    Some(b.chunks_exact(8).map(|c| {
        let mut a = [0u8; 8];
        a.copy_from_slice(c);
        a
    }))
}

#[derive(serde::Serialize, serde::Deserialize)]
struct TableJson {
    name: String,
    columns: Vec<String>,
    rows: Vec<Vec<f64>>,
}

#[derive(serde::Serialize, serde::Deserialize)]
struct FigureJson {
    name: String,
    svg: String,
}

const JOB_COLUMNS: &str = "id, name, spec_json, state, created_ms, started_ms, finished_ms, error_field, error_reason, done, total, t";

/// A job's status and its spec (JSON) from a `SELECT {JOB_COLUMNS}` row.
fn row_to_job(r: &rusqlite::Row<'_>) -> rusqlite::Result<((JobView, String), String)> {
    let state: String = r.get(3)?;
    let field: Option<String> = r.get(7)?;
    let reason: Option<String> = r.get(8)?;
    Ok((
        (
            JobView {
                id: r.get(0)?,
                name: r.get(1)?,
                state: JobState::Queued,
                created_ms: r.get::<_, i64>(4)? as u64,
                started_ms: r.get::<_, i64>(5)? as u64,
                finished_ms: r.get::<_, i64>(6)? as u64,
                error: match (field, reason) {
                    (Some(f), Some(r)) => Some((f, r)),
                    _ => None,
                },
                done: r.get::<_, i64>(9)? as u64,
                total: r.get::<_, i64>(10)? as u64,
                t: r.get(11)?,
            },
            r.get(2)?,
        ),
        state,
    ))
}

fn finish_row(
    ((mut view, spec_json), state): ((JobView, String), String),
) -> Result<(JobView, String), StoreError> {
    view.state = JobState::parse(&state).ok_or_else(|| StoreError::Corrupt {
        what: "state",
        id: view.id.clone(),
    })?;
    Ok((view, spec_json))
}

impl Store {
    /// Opens (or creates) the store at `path` in WAL mode. `:memory:` gives a throwaway store.
    pub fn open(path: &Path) -> Result<Store, StoreError> {
        let conn = Connection::open(path)?;
        // WAL + synchronous=NORMAL: a committed transaction survives a process crash.
        conn.pragma_update(None, "journal_mode", "WAL")?;
        conn.pragma_update(None, "synchronous", "NORMAL")?;
        conn.busy_timeout(std::time::Duration::from_secs(5))?;
        conn.execute_batch(SCHEMA)?;
        migrate(&conn)?;
        Ok(Store {
            conn: Mutex::new(conn),
        })
    }

    fn conn(&self) -> std::sync::MutexGuard<'_, Connection> {
        // A panic while holding the lock leaves SQLite consistent (transactions roll back).
        self.conn.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Records a new queued job with its spec (JSON). False when the id is taken.
    pub fn insert(&self, row: &JobView, spec_json: &str) -> Result<bool, StoreError> {
        let n = self.conn().execute(
            "INSERT OR IGNORE INTO jobs (id, name, spec_json, state, created_ms, total) VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
            params![row.id, row.name, spec_json, row.state.as_str(), row.created_ms as i64, row.total as i64],
        )?;
        Ok(n == 1)
    }

    /// Marks a job running.
    pub fn set_running(&self, id: &str, started_ms: u64) -> Result<(), StoreError> {
        self.conn().execute(
            "UPDATE jobs SET state = 'running', started_ms = ?2 WHERE id = ?1",
            params![id, started_ms as i64],
        )?;
        Ok(())
    }

    /// Ends a job: its final state, error, progress and (for a success) its result, in one
    /// transaction.
    pub fn finish(&self, row: &JobView, result: Option<&StoredResult>) -> Result<(), StoreError> {
        let mut conn = self.conn();
        let tx = conn.transaction()?;
        if let Some(r) = result {
            let tables: Vec<TableJson> = r
                .tables
                .iter()
                .map(|t| TableJson {
                    name: t.name.clone(),
                    columns: t.columns.clone(),
                    rows: t.rows.clone(),
                })
                .collect();
            let figures: Vec<FigureJson> = r
                .figures
                .iter()
                .map(|f| FigureJson {
                    name: f.name.clone(),
                    svg: f.svg.clone(),
                })
                .collect();
            tx.execute(
                "INSERT OR REPLACE INTO results (id, summary_json, columns_json, steps, t, vals, tables_json, figures_json)
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)",
                params![
                    row.id,
                    serde_json::to_string(&r.summary).unwrap_or_else(|_| "{}".into()),
                    serde_json::to_string(&r.columns).unwrap_or_else(|_| "[]".into()),
                    u64s_to_blob(&r.steps),
                    f64s_to_blob(&r.t),
                    f64s_to_blob(&r.values),
                    serde_json::to_string(&tables).unwrap_or_else(|_| "[]".into()),
                    serde_json::to_string(&figures).unwrap_or_else(|_| "[]".into()),
                ],
            )?;
        }
        let (field, reason) = match &row.error {
            Some((f, r)) => (Some(f.as_str()), Some(r.as_str())),
            None => (None, None),
        };
        tx.execute(
            "UPDATE jobs SET state = ?2, finished_ms = ?3, error_field = ?4, error_reason = ?5, done = ?6, total = ?7, t = ?8
             WHERE id = ?1",
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
        tx.commit()?;
        Ok(())
    }

    /// One job's status.
    pub fn get(&self, id: &str) -> Result<Option<JobView>, StoreError> {
        let conn = self.conn();
        let row = conn
            .query_row(
                &format!("SELECT {JOB_COLUMNS} FROM jobs WHERE id = ?1"),
                [id],
                row_to_job,
            )
            .optional()?;
        Ok(row.map(finish_row).transpose()?.map(|(view, _)| view))
    }

    /// Every job's status, oldest first.
    pub fn list(&self) -> Result<Vec<JobView>, StoreError> {
        Ok(self
            .list_with_specs()?
            .into_iter()
            .map(|(view, _)| view)
            .collect())
    }

    /// Every job's status and spec (JSON), oldest first.
    fn list_with_specs(&self) -> Result<Vec<(JobView, String)>, StoreError> {
        let conn = self.conn();
        let mut stmt = conn.prepare(&format!("SELECT {JOB_COLUMNS} FROM jobs ORDER BY seq"))?;
        let rows = stmt
            .query_map([], row_to_job)?
            .collect::<Result<Vec<_>, _>>()?;
        rows.into_iter().map(finish_row).collect()
    }

    /// At start-up: every job that was queued or running when the last process stopped, oldest
    /// first, now marked queued again, with its spec (JSON).
    pub fn recover(&self) -> Result<Vec<(JobView, String)>, StoreError> {
        self.conn().execute(
            "UPDATE jobs SET state = 'queued', started_ms = 0 WHERE state = 'running'",
            [],
        )?;
        Ok(self
            .list_with_specs()?
            .into_iter()
            .filter(|(r, _)| r.state == JobState::Queued)
            .collect())
    }

    /// Number of jobs per state.
    pub fn counts(&self) -> Result<Vec<(JobState, u64)>, StoreError> {
        let conn = self.conn();
        let mut stmt = conn.prepare("SELECT state, COUNT(*) FROM jobs GROUP BY state")?;
        let rows = stmt
            .query_map([], |r| {
                Ok((r.get::<_, String>(0)?, r.get::<_, i64>(1)? as u64))
            })?
            .collect::<Result<Vec<_>, _>>()?;
        Ok(JobState::ALL
            .into_iter()
            .map(|s| {
                (
                    s,
                    rows.iter()
                        .find(|(n, _)| n == s.as_str())
                        .map_or(0, |(_, c)| *c),
                )
            })
            .collect())
    }

    /// The result of a succeeded job.
    pub fn result(&self, id: &str) -> Result<Option<StoredResult>, StoreError> {
        let conn = self.conn();
        let raw = conn
            .query_row(
                "SELECT summary_json, columns_json, steps, t, vals, tables_json, figures_json FROM results WHERE id = ?1",
                [id],
                |r| {
                    Ok((
                        r.get::<_, String>(0)?,
                        r.get::<_, String>(1)?,
                        r.get::<_, Vec<u8>>(2)?,
                        r.get::<_, Vec<u8>>(3)?,
                        r.get::<_, Vec<u8>>(4)?,
                        r.get::<_, String>(5)?,
                        r.get::<_, String>(6)?,
                    ))
                },
            )
            .optional()?;
        let Some((summary, columns, steps, t, vals, tables, figures)) = raw else {
            return Ok(None);
        };
        let corrupt = |what| StoreError::Corrupt {
            what,
            id: id.to_string(),
        };
        let summary: Map<String, Value> =
            serde_json::from_str(&summary).map_err(|_| corrupt("summary"))?;
        let columns: Vec<String> =
            serde_json::from_str(&columns).map_err(|_| corrupt("columns"))?;
        let tables: Vec<TableJson> =
            serde_json::from_str(&tables).map_err(|_| corrupt("tables"))?;
        let figures: Vec<FigureJson> =
            serde_json::from_str(&figures).map_err(|_| corrupt("figures"))?;
        let steps: Vec<u64> = blob_to_8(&steps)
            .ok_or_else(|| corrupt("steps"))?
            .map(u64::from_le_bytes)
            .collect();
        let t: Vec<f64> = blob_to_8(&t)
            .ok_or_else(|| corrupt("t"))?
            .map(f64::from_le_bytes)
            .collect();
        let values: Vec<f64> = blob_to_8(&vals)
            .ok_or_else(|| corrupt("values"))?
            .map(f64::from_le_bytes)
            .collect();
        if t.len() != steps.len() || values.len() != steps.len() * columns.len() {
            return Err(corrupt("series"));
        }
        Ok(Some(StoredResult {
            summary,
            columns,
            steps,
            t,
            values,
            tables: tables
                .into_iter()
                .map(|t| Table {
                    name: t.name,
                    columns: t.columns,
                    rows: t.rows,
                })
                .collect(),
            figures: figures
                .into_iter()
                .map(|f| Figure {
                    name: f.name,
                    svg: f.svg,
                })
                .collect(),
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(id: &str) -> JobView {
        JobView {
            id: id.into(),
            name: None,
            state: JobState::Queued,
            created_ms: 1,
            started_ms: 0,
            finished_ms: 0,
            error: None,
            done: 0,
            total: 10,
            t: 0.0,
        }
    }

    #[test]
    fn result_round_trips_bit_for_bit_and_running_jobs_recover_as_queued() -> Result<(), StoreError>
    {
        let dir = tempfile::tempdir().map_err(|_| StoreError::Corrupt {
            what: "tmp",
            id: String::new(),
        })?;
        let path = dir.path().join("s.db");
        {
            let s = Store::open(&path)?;
            assert!(s.insert(&row("a"), "{}")?);
            assert!(!s.insert(&row("a"), "{}")?);
            assert!(s.insert(&row("b"), "{}")?);
            s.set_running("b", 5)?;
            let r = StoredResult {
                columns: vec!["x".into(), "y".into()],
                steps: vec![0, 1],
                t: vec![0.0, 0.1],
                values: vec![1.0 / 3.0, f64::MIN_POSITIVE, -0.0, 1e300],
                ..Default::default()
            };
            let mut done = row("a");
            done.state = JobState::Succeeded;
            s.finish(&done, Some(&r))?;
            let back = s.result("a")?.ok_or(StoreError::Corrupt {
                what: "missing",
                id: "a".into(),
            })?;
            assert_eq!(
                back.values.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                r.values.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
            );
            assert_eq!(back.column(1), vec![f64::MIN_POSITIVE, 1e300]);
        }
        let s = Store::open(&path)?;
        let again = s.recover()?;
        assert_eq!(
            again.iter().map(|(r, _)| r.id.as_str()).collect::<Vec<_>>(),
            vec!["b"]
        );
        assert_eq!(s.get("a")?.map(|r| r.state), Some(JobState::Succeeded));
        Ok(())
    }

    fn tmp() -> Result<tempfile::TempDir, StoreError> {
        tempfile::tempdir().map_err(|_| StoreError::Corrupt {
            what: "tmp",
            id: String::new(),
        })
    }

    fn missing(id: &str) -> StoreError {
        StoreError::Corrupt {
            what: "missing",
            id: id.into(),
        }
    }

    #[test]
    fn figures_round_trip_and_are_found_with_or_without_svg() -> Result<(), StoreError> {
        let dir = tmp()?;
        let s = Store::open(&dir.path().join("s.db"))?;
        assert!(s.insert(&row("f"), "{}")?);
        let figures = vec![
            Figure {
                name: "backbone".into(),
                svg: "<svg xmlns=\"http://www.w3.org/2000/svg\">ω ≤ \"1\"</svg>\n".into(),
            },
            Figure {
                name: "orbit_gap_0".into(),
                svg: "<svg/>".into(),
            },
        ];
        let mut done = row("f");
        done.state = JobState::Succeeded;
        s.finish(
            &done,
            Some(&StoredResult {
                figures: figures.clone(),
                ..Default::default()
            }),
        )?;
        let back = s.result("f")?.ok_or_else(|| missing("f"))?;
        assert_eq!(back.figures, figures);
        assert_eq!(back.figure("backbone"), Some(&figures[0]));
        assert_eq!(back.figure("orbit_gap_0.svg"), Some(&figures[1]));
        assert_eq!(back.figure("../backbone"), None);
        assert_eq!(back.figure("nope"), None);
        Ok(())
    }

    #[test]
    fn corrupt_figures_are_reported_as_corrupt() -> Result<(), StoreError> {
        let dir = tmp()?;
        let s = Store::open(&dir.path().join("s.db"))?;
        assert!(s.insert(&row("c"), "{}")?);
        let mut done = row("c");
        done.state = JobState::Succeeded;
        s.finish(&done, Some(&StoredResult::default()))?;
        s.conn().execute(
            "UPDATE results SET figures_json = '{not json' WHERE id = 'c'",
            [],
        )?;
        match s.result("c") {
            Err(StoreError::Corrupt { what, id }) => {
                assert_eq!((what, id.as_str()), ("figures", "c"));
            }
            other => panic!("expected a corrupt-figures error, got {other:?}"),
        }
        Ok(())
    }

    /// A database written before figures were stored (the exact `results` table of that schema)
    /// opens, keeps its result, reads back with no figures, and takes figures afterwards.
    #[test]
    fn a_database_of_the_schema_without_figures_is_migrated() -> Result<(), StoreError> {
        let dir = tmp()?;
        let path = dir.path().join("old.db");
        {
            let conn = Connection::open(&path)?;
            conn.execute_batch(
                "
CREATE TABLE IF NOT EXISTS jobs (
    seq INTEGER PRIMARY KEY AUTOINCREMENT,
    id TEXT NOT NULL UNIQUE,
    name TEXT,
    spec_json TEXT NOT NULL,
    state TEXT NOT NULL,
    created_ms INTEGER NOT NULL,
    started_ms INTEGER NOT NULL DEFAULT 0,
    finished_ms INTEGER NOT NULL DEFAULT 0,
    error_field TEXT,
    error_reason TEXT,
    done INTEGER NOT NULL DEFAULT 0,
    total INTEGER NOT NULL DEFAULT 0,
    t REAL NOT NULL DEFAULT 0
);
CREATE TABLE IF NOT EXISTS results (
    id TEXT PRIMARY KEY REFERENCES jobs(id),
    summary_json TEXT NOT NULL,
    columns_json TEXT NOT NULL,
    steps BLOB NOT NULL,
    t BLOB NOT NULL,
    vals BLOB NOT NULL,
    tables_json TEXT NOT NULL
);
INSERT INTO jobs (id, spec_json, state, created_ms, finished_ms, done, total, t)
    VALUES ('old', '{}', 'succeeded', 1, 2, 1, 1, 0.5);
",
            )?;
            conn.execute(
                "INSERT INTO results (id, summary_json, columns_json, steps, t, vals, tables_json)
                 VALUES ('old', '{\"steps\":1}', '[\"x\"]', ?1, ?2, ?3, '[{\"name\":\"backbone\",\"columns\":[\"m\"],\"rows\":[[1.0]]}]')",
                params![
                    u64s_to_blob(&[0, 1]),
                    f64s_to_blob(&[0.0, 0.5]),
                    f64s_to_blob(&[1.5, 2.5])
                ],
            )?;
        }
        for _ in 0..2 {
            // Twice: the second open finds the column already there.
            let s = Store::open(&path)?;
            let back = s.result("old")?.ok_or_else(|| missing("old"))?;
            assert_eq!(back.summary.get("steps"), Some(&serde_json::json!(1)));
            assert_eq!(back.steps, vec![0, 1]);
            assert_eq!(back.column(0), vec![1.5, 2.5]);
            assert_eq!(back.tables.len(), 1);
            assert!(back.figures.is_empty());
            assert_eq!(s.get("old")?.map(|r| r.state), Some(JobState::Succeeded));
        }
        let s = Store::open(&path)?;
        assert!(s.insert(&row("new"), "{}")?);
        let mut done = row("new");
        done.state = JobState::Succeeded;
        let fig = Figure {
            name: "energy".into(),
            svg: "<svg/>".into(),
        };
        s.finish(
            &done,
            Some(&StoredResult {
                figures: vec![fig.clone()],
                ..Default::default()
            }),
        )?;
        assert_eq!(
            s.result("new")?.ok_or_else(|| missing("new"))?.figures,
            vec![fig]
        );
        Ok(())
    }
}
