//! `signorini compare DIR...`: several runs' results side by side — one figure per chosen
//! column with a curve per run, and a table of what each run's summary.json says about speed,
//! energy and round-off (also written as `compare.csv`).

use crate::output::{fmt_value, write_atomic, write_figure};
use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use serde_json::{Map, Value};
use signorini_core::trace::Envelope;
use signorini_figures::{Curve, line_chart};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};

/// `signorini compare`.
#[derive(Debug, Args)]
#[command(after_help = "Example:
  signorini run examples/bar.toml --out out/mj
  signorini run examples/bar_ns_generalized_alpha.toml --out out/ga
  signorini compare out/mj out/ga --column energy --column balance_residual

Writes OUT/compare_COLUMN.svg per column (residuals and energy_error are drawn as
log10 |value|) and OUT/compare.csv, and prints the table (with max_abs_balance_residual and/or
max_abs_energy_error, whichever the runs report).")]
pub struct CompareArgs {
    /// Result directories written by `signorini run` or `signorini result --out`.
    #[arg(required = true, num_args = 2..)]
    pub dirs: Vec<PathBuf>,
    /// A steps.csv column to draw (repeat for several) [default: energy, and the runs' check:
    /// balance_residual, or energy_error for the nonlinear families].
    #[arg(long = "column", short)]
    pub columns: Vec<String>,
    /// Directory for the figures and compare.csv.
    #[arg(long, short, default_value = "compare")]
    pub out: PathBuf,
}

/// Summary fields of the table, in order (absent ones are left empty). The two checks (the
/// balance residual of the linear schemes, the energy error of the nonlinear ones) are columns
/// only when a run has them ([`CHECKS`]).
const TABLE: [&str; 10] = [
    "steps",
    "h",
    "wall_s",
    "steps_per_s",
    "energy_initial",
    "energy_final",
    "energy_max",
    "max_abs_balance_residual",
    "max_abs_energy_error",
    "impacts",
];

/// Table fields shown only when some run has them.
const CHECKS: [&str; 2] = ["max_abs_balance_residual", "max_abs_energy_error"];

/// The steps.csv columns a comparison draws by default: `energy` and the runs' check.
fn default_columns(dirs: &[PathBuf]) -> Vec<String> {
    let has = |column: &str| {
        dirs.iter().all(|d| {
            std::fs::File::open(d.join("steps.csv"))
                .ok()
                .and_then(|f| BufReader::new(f).lines().next()?.ok())
                .is_some_and(|header| header.split(',').any(|n| n == column))
        })
    };
    let check = ["balance_residual", "energy_error"]
        .into_iter()
        .find(|c| has(c))
        .unwrap_or("balance_residual");
    vec!["energy".to_string(), check.to_string()]
}

/// Whether a column is drawn as log₁₀ |value| (a residual or an energy error).
fn is_log(column: &str) -> bool {
    column.ends_with("residual") || column == "energy_error"
}

const COLORS: [&str; 8] = [
    "black", "#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2",
];

/// One run: its label, summary and the envelope of each chosen column.
struct Run {
    label: String,
    summary: Map<String, Value>,
    envelopes: Vec<Envelope>,
}

/// A label: the directory's name, then the scheme and h from the summary.
fn label(dir: &Path, summary: &Map<String, Value>) -> String {
    let name = dir
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| dir.display().to_string());
    let scheme = summary.get("scheme").and_then(Value::as_str);
    let h = summary.get("h").and_then(Value::as_f64);
    match (scheme, h) {
        (Some(s), Some(h)) => format!("{name}: {s}, h = {h}"),
        (Some(s), None) => format!("{name}: {s}"),
        _ => name,
    }
}

fn read_run(dir: &Path, columns: &[String]) -> Result<Run> {
    let path = dir.join("summary.json");
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("{}: not a finished result", path.display()))?;
    let summary: Map<String, Value> =
        serde_json::from_str(&text).with_context(|| format!("reading {}", path.display()))?;
    let path = dir.join("steps.csv");
    let file = std::fs::File::open(&path).with_context(|| {
        format!(
            "{}: no step table (an analysis records no steps)",
            path.display()
        )
    })?;
    let mut lines = BufReader::new(file).lines();
    let header = lines
        .next()
        .transpose()?
        .ok_or_else(|| anyhow!("{}: empty", path.display()))?;
    let names: Vec<&str> = header.split(',').collect();
    let t_at = names
        .iter()
        .position(|n| *n == "t")
        .ok_or_else(|| anyhow!("{}: no column t", path.display()))?;
    let at: Vec<usize> = columns
        .iter()
        .map(|c| {
            names.iter().position(|n| n == c).ok_or_else(|| {
                anyhow!(
                    "{}: no column {c:?} (it has {})",
                    path.display(),
                    names[2.min(names.len())..].join(", ")
                )
            })
        })
        .collect::<Result<_>>()?;
    let mut envelopes: Vec<Envelope> = columns.iter().map(|c| Envelope::new(is_log(c))).collect();
    for (row, line) in lines.enumerate() {
        let line = line?;
        let cells: Vec<&str> = line.split(',').collect();
        let value = |i: usize| -> Result<f64> {
            cells
                .get(i)
                .and_then(|c| c.parse::<f64>().ok())
                .ok_or_else(|| anyhow!("{}: row {}: bad value", path.display(), row + 2))
        };
        let t = value(t_at)?;
        for (e, &i) in envelopes.iter_mut().zip(&at) {
            e.push(t, value(i)?);
        }
    }
    Ok(Run {
        label: label(dir, &summary),
        summary,
        envelopes,
    })
}

/// Runs the command.
pub fn compare(mut args: CompareArgs) -> Result<()> {
    if args.columns.is_empty() {
        args.columns = default_columns(&args.dirs);
    }
    let runs: Vec<Run> = args
        .dirs
        .iter()
        .map(|d| read_run(d, &args.columns))
        .collect::<Result<_>>()?;
    let fields: Vec<&str> = TABLE
        .into_iter()
        .filter(|f| !CHECKS.contains(f) || runs.iter().any(|r| r.summary.contains_key(*f)))
        .collect();
    if runs.len() > COLORS.len() {
        bail!("at most {} runs per comparison", COLORS.len());
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    for (k, column) in args.columns.iter().enumerate() {
        let log = is_log(column);
        let curves: Vec<Curve> = runs
            .iter()
            .zip(COLORS)
            .map(|(r, color)| Curve {
                label: r.label.clone(),
                color,
                dash: "",
                points: r.envelopes[k].points().collect(),
            })
            .collect();
        let (title, ylabel) = if log {
            (format!("log₁₀ |{column}|"), format!("log₁₀ |{column}|"))
        } else {
            (column.clone(), column.clone())
        };
        let figure = line_chart(&format!("compare_{column}"), &title, &ylabel, log, &curves);
        write_figure(&args.out, &figure)?;
    }
    let mut csv = String::from("run");
    for f in &fields {
        csv.push(',');
        csv.push_str(f);
    }
    csv.push('\n');
    let wide = runs
        .iter()
        .map(|r| r.label.chars().count())
        .max()
        .unwrap_or(3);
    let mut table = format!("{:<wide$}", "run");
    for f in &fields {
        table.push_str(&format!(" {f:>w$}", w = f.len().max(12)));
    }
    table.push('\n');
    for r in &runs {
        csv.push_str(&format!("\"{}\"", r.label.replace('"', "'")));
        table.push_str(&format!("{:<wide$}", r.label));
        for f in &fields {
            let v = r.summary.get(*f).and_then(Value::as_f64);
            csv.push(',');
            csv.push_str(&v.map(fmt_value).unwrap_or_default());
            let cell = match v {
                Some(x) if x.fract() == 0.0 && x.abs() < 1e15 => format!("{x:.0}"),
                Some(x) => format!("{x:.4e}"),
                None => String::new(),
            };
            table.push_str(&format!(" {cell:>w$}", w = f.len().max(12)));
        }
        csv.push('\n');
        table.push('\n');
    }
    write_atomic(&args.out.join("compare.csv"), &csv)?;
    print!("{table}");
    println!("figures and compare.csv in {}", args.out.display());
    Ok(())
}
