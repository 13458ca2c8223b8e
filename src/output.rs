//! A finished run's results and their files: [`finish_run`] attaches the wall time to a run's
//! output (for `signorini run` and the service alike), and the writers here make `steps.csv`
//! (header `step,t,` then the run's columns), `summary.json`, one `NAME.csv` per extra table and
//! one `NAME.svg` per figure, for `signorini run` and `signorini result --out` alike.
//!
//! Files are written under a temporary name and renamed when complete, and stale results of an
//! earlier run in the same directory are removed first: a failed run never leaves files that
//! look like valid results.

use anyhow::{Context, Result, anyhow};
use serde_json::{Map, Value};
use signorini_core::observer::{Columns, Observer, StepRecord};
use signorini_core::outcome::{RunOutput, Table};
use signorini_figures::Figure;
use std::fs::{self, File};
use std::io::{BufWriter, Write};
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// A finished run's results besides its step series: what `summary.json`, the tables and the
/// figures hold.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FinishedRun {
    /// `summary.json`, with `wall_s` and `steps_per_s`.
    pub summary: Map<String, Value>,
    /// Extra tables (`NAME.csv`).
    pub tables: Vec<Table>,
    /// Figures (`NAME.svg`).
    pub figures: Vec<Figure>,
}

/// A run's output with its wall time attached once ([`RunSummary::with_timing`]: `wall_s` and
/// `steps_per_s`, 0 for a run that took no measurable time, after the run's own entries) and its
/// chart data drawn as figures.
///
/// [`RunSummary::with_timing`]: signorini_core::outcome::RunSummary::with_timing
pub fn finish_run(output: RunOutput, wall: Duration) -> FinishedRun {
    let RunOutput {
        summary,
        tables,
        charts,
    } = output;
    FinishedRun {
        summary: summary.with_timing(wall).to_map(),
        tables,
        figures: signorini_figures::render(&charts),
    }
}

/// Formats one value as CSV: shortest text that reads back to the same f64.
pub fn fmt_value(x: f64) -> String {
    format!("{x:?}")
}

/// The CSV header of a step table.
fn csv_header(columns: &[String]) -> String {
    let mut s = String::from("step,t");
    for c in columns {
        s.push(',');
        s.push_str(c);
    }
    s
}

/// An [`Observer`] writing `steps.csv` rows as they come.
pub struct CsvSteps {
    path: PathBuf,
    partial: PathBuf,
    out: BufWriter<File>,
    error: Option<std::io::Error>,
    started: bool,
    /// Continuing a resumed run: the header and the first records are in the file already.
    resumed: bool,
}

/// The checkpoint of a run in its output directory, written with [`write_checkpoint`].
pub const CHECKPOINT_FILE: &str = "checkpoint.bin";
/// The spec of a run that can be resumed (JSON), next to its checkpoint.
pub const RUN_SPEC_FILE: &str = "run_spec.json";

impl CsvSteps {
    /// Opens `DIR/steps.csv.partial` for writing.
    pub fn create(dir: &Path) -> Result<Self> {
        let path = dir.join("steps.csv");
        let partial = dir.join("steps.csv.partial");
        let file =
            File::create(&partial).with_context(|| format!("creating {}", partial.display()))?;
        Ok(Self {
            path,
            partial,
            out: BufWriter::with_capacity(1 << 20, file),
            error: None,
            started: false,
            resumed: false,
        })
    }

    /// Reopens `DIR/steps.csv.partial` of an interrupted run to continue it after its first
    /// `records` records: rows written after the checkpoint (and a row cut by the kill) are
    /// dropped, so the file continues exactly where the checkpoint left it.
    pub fn resume(dir: &Path, records: u64) -> Result<Self> {
        let path = dir.join("steps.csv");
        let partial = dir.join("steps.csv.partial");
        let bytes = fs::read(&partial).with_context(|| format!("reading {}", partial.display()))?;
        // The header line and `records` rows.
        let keep_lines = records + 1;
        let mut lines = 0u64;
        let mut end = None;
        for (i, &b) in bytes.iter().enumerate() {
            if b == b'\n' {
                lines += 1;
                if lines == keep_lines {
                    end = Some(i + 1);
                    break;
                }
            }
        }
        let Some(end) = end else {
            return Err(anyhow!(
                "{} has {lines} complete lines, the checkpoint needs {keep_lines}",
                partial.display()
            ));
        };
        let file = fs::OpenOptions::new()
            .write(true)
            .open(&partial)
            .with_context(|| format!("opening {}", partial.display()))?;
        file.set_len(end as u64)
            .with_context(|| format!("truncating {}", partial.display()))?;
        let mut file = file;
        std::io::Seek::seek(&mut file, std::io::SeekFrom::End(0))
            .with_context(|| format!("seeking {}", partial.display()))?;
        Ok(Self {
            path,
            partial,
            out: BufWriter::with_capacity(1 << 20, file),
            error: None,
            started: true,
            resumed: true,
        })
    }

    /// Writes the rows so far to the disk (before a checkpoint that counts them is written).
    pub fn sync(&mut self) -> Result<()> {
        if let Some(e) = self.error.take() {
            return Err(e).context("writing steps.csv");
        }
        self.out.flush().context("writing steps.csv")?;
        self.out.get_ref().sync_data().context("syncing steps.csv")
    }

    fn write_row(&mut self, r: &StepRecord<'_>) -> std::io::Result<()> {
        write!(self.out, "{},{:?}", r.step, r.t)?;
        for v in r.values {
            write!(self.out, ",{v:?}")?;
        }
        writeln!(self.out)
    }

    /// Flushes and renames to `steps.csv`; a run that records no steps (an analysis) leaves
    /// no steps.csv at all rather than an empty file.
    pub fn finish(mut self) -> Result<()> {
        if let Some(e) = self.error.take() {
            return Err(e).context("writing steps.csv");
        }
        if !self.started {
            self.discard();
            return Ok(());
        }
        self.out.flush().context("writing steps.csv")?;
        drop(self.out);
        fs::rename(&self.partial, &self.path).context("renaming steps.csv")
    }

    /// Removes the partial file (after a failed run).
    pub fn discard(self) {
        drop(self.out);
        let _ = fs::remove_file(&self.partial);
    }
}

impl Observer for CsvSteps {
    fn start(&mut self, columns: &Columns) {
        self.started = true;
        if self.resumed {
            return;
        }
        if let Err(e) = writeln!(self.out, "{}", csv_header(columns.names())) {
            self.error = Some(e);
        }
    }

    fn observe(&mut self, record: &StepRecord<'_>) -> ControlFlow<()> {
        match self.write_row(record) {
            Ok(()) => ControlFlow::Continue(()),
            Err(e) => {
                self.error = Some(e);
                ControlFlow::Break(())
            }
        }
    }
}

/// Removes the results of an earlier run from `dir`: `steps.csv`, `summary.json` and unfinished
/// `*.partial` files. Tables and figures are left (they are replaced atomically when a run
/// writes them); `summary.json`, written last, is what marks a directory as a complete result.
/// Other files are never touched, so `--out .` is safe.
pub fn clear_results(dir: &Path) -> Result<()> {
    let mut stale = vec![dir.join("steps.csv"), dir.join("summary.json")];
    if let Ok(entries) = fs::read_dir(dir) {
        stale.extend(
            entries
                .flatten()
                .map(|e| e.path())
                .filter(|p| p.extension().is_some_and(|x| x == "partial")),
        );
    }
    for p in stale {
        match fs::remove_file(&p) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(e).with_context(|| format!("removing stale {}", p.display())),
        }
    }
    Ok(())
}

/// Writes a run's checkpoint to `DIR/checkpoint.bin` atomically and durably: a temporary file,
/// synced, renamed over the last one, so a kill at any moment leaves the previous checkpoint or
/// this one, never a mix.
pub fn write_checkpoint(dir: &Path, bytes: &[u8]) -> Result<()> {
    let path = dir.join(CHECKPOINT_FILE);
    let tmp = dir.join(format!("{CHECKPOINT_FILE}.partial"));
    let mut f = File::create(&tmp).with_context(|| format!("creating {}", tmp.display()))?;
    f.write_all(bytes)
        .and_then(|()| f.sync_data())
        .with_context(|| format!("writing {}", tmp.display()))?;
    drop(f);
    fs::rename(&tmp, &path).with_context(|| format!("renaming {}", path.display()))
}

/// Removes what lets a run be resumed (`checkpoint.bin`, `run_spec.json`): after it finished,
/// or before a fresh run in the same directory.
pub fn clear_checkpoint(dir: &Path) -> Result<()> {
    for name in [CHECKPOINT_FILE, RUN_SPEC_FILE] {
        let p = dir.join(name);
        match fs::remove_file(&p) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(e).with_context(|| format!("removing {}", p.display())),
        }
    }
    Ok(())
}

/// Writes `text` to `path` atomically (temporary file, then rename).
pub fn write_atomic(path: &Path, text: &str) -> Result<()> {
    let tmp = path.with_extension("partial");
    fs::write(&tmp, text).with_context(|| format!("writing {}", tmp.display()))?;
    fs::rename(&tmp, path).with_context(|| format!("renaming {}", path.display()))
}

/// Writes a finished run's tables (`NAME.csv`), figures (`NAME.svg`) and, last, `summary.json`
/// to `dir` (the step series is written by [`CsvSteps`]). Names that are not
/// plain file stems are refused, so no name (they may come from a server) reaches outside `dir`.
pub fn write_run_files(dir: &Path, run: &FinishedRun) -> Result<()> {
    for t in &run.tables {
        check_stem("table", &t.name)?;
        write_table(dir, t)?;
    }
    for f in &run.figures {
        check_stem("figure", &f.name)?;
        write_figure(dir, f)?;
    }
    // Written last: its presence marks a complete result.
    let text = serde_json::to_string_pretty(&run.summary)?;
    write_atomic(&dir.join("summary.json"), &(text + "\n"))
}

/// Refuses a table or figure name that is not made of `[A-Za-z0-9_-]` (the names the core gives),
/// so `NAME.csv` and `NAME.svg` stay in their directory.
fn check_stem(what: &str, name: &str) -> Result<()> {
    let stem = !name.is_empty()
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-');
    if !stem {
        return Err(anyhow!("{what} name {name:?} is not a file stem"));
    }
    Ok(())
}

/// Writes a table as CSV.
fn write_table(dir: &Path, table: &Table) -> Result<()> {
    let mut s = table.columns.join(",");
    s.push('\n');
    for row in &table.rows {
        let cells: Vec<String> = row.iter().map(|&x| fmt_value(x)).collect();
        s.push_str(&cells.join(","));
        s.push('\n');
    }
    write_atomic(&dir.join(format!("{}.csv", table.name)), &s)
}

/// Writes a figure as SVG.
pub fn write_figure(dir: &Path, figure: &Figure) -> Result<()> {
    write_atomic(&dir.join(format!("{}.svg", figure.name)), &figure.svg)
}
