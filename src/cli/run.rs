//! `signorini run SPEC --out DIR`: validate a spec, run it in-process, write the results.

use crate::output::{
    CsvSteps, clear_results, finish_run, write_atomic, write_figure, write_run_files,
};
use crate::spec_file::{self, Format};
use anyhow::{Context, Result, anyhow};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use signorini_core::job::{self, Job};
use signorini_core::observer::{Columns, Observer, Progress, StepRecord};
use signorini_core::outcome::RunOutput;
use std::ops::ControlFlow;
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// Arguments of `signorini run`.
#[derive(Debug, Args)]
#[command(after_help = "\
The spec is TOML (or JSON if the file ends in .json) with the sections
[model] (scene = bouncing_ball | bar | dep_bar | chain | linear …), [integrator] (scheme = moreau_jean …),
[time] (h, t_end or steps), [contact_solver], [output] (every, probes). Examples: examples/*.toml

Writes DIR/steps.csv (step, t, energy terms, gap/u/p per contact, q/v per probe) and
DIR/summary.json (steps, wall_s, steps_per_s, max_abs_balance_residual, energies, impacts, …).

  signorini run examples/bouncing_ball.toml --out out/ball")]
pub struct RunArgs {
    /// Job spec file (TOML, or JSON when it ends in .json).
    pub spec: PathBuf,
    /// Directory for steps.csv and summary.json (created if missing).
    #[arg(long, short, default_value = "out")]
    pub out: PathBuf,
    /// No progress bar and no summary on stdout.
    #[arg(long, short)]
    pub quiet: bool,
}

/// Writes rows to steps.csv and drives a progress bar.
struct CliObserver {
    csv: CsvSteps,
    bar: ProgressBar,
    last_draw: Instant,
}

impl Observer for CliObserver {
    fn start(&mut self, columns: &Columns) {
        self.csv.start(columns);
    }

    fn observe(&mut self, record: &StepRecord<'_>) -> ControlFlow<()> {
        self.csv.observe(record)
    }

    fn progress(&mut self, p: Progress) -> ControlFlow<()> {
        if p.done.is_multiple_of(1024) && self.last_draw.elapsed() > Duration::from_millis(100) {
            self.bar.set_length(p.total);
            self.bar.set_position(p.done);
            self.last_draw = Instant::now();
        }
        ControlFlow::Continue(())
    }
}

/// Runs the command.
pub fn run(args: RunArgs) -> Result<()> {
    // DIR holds the results of the last run or nothing: stale results go first, so a refused
    // spec or a failed run cannot leave files that look valid.
    if args.out.is_dir() {
        clear_results(&args.out)?;
    }
    let text = std::fs::read_to_string(&args.spec)
        .with_context(|| format!("reading {}", args.spec.display()))?;
    let spec = spec_file::parse(&text, Format::of_path(&args.spec))
        .map_err(|e| anyhow!("invalid spec {}: {e}", args.spec.display()))?;
    if spec.study.is_some() {
        return run_study(&args, &spec);
    }
    let job =
        Job::from_spec(&spec).map_err(|e| anyhow!("invalid spec {}: {e}", args.spec.display()))?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;

    let bar = if args.quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(job.size().steps)
    };
    bar.set_style(
        ProgressStyle::with_template(
            "{elapsed_precise} [{bar:40}] {pos}/{len} steps ({per_sec}, eta {eta})",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let mut observer = CliObserver {
        csv: CsvSteps::create(&args.out)?,
        bar,
        last_draw: Instant::now(),
    };
    let started = Instant::now();
    // The CLI runs one job: it may use every core for an analysis's parallel scans.
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let result = job::run(&job, threads, &mut observer);
    let wall = started.elapsed();
    observer.bar.finish_and_clear();
    let output: RunOutput = match result {
        Ok(o) => o,
        Err(e) => {
            observer.csv.discard();
            return Err(anyhow!("run failed: {e}"));
        }
    };
    observer.csv.finish()?;
    let run = finish_run(output, wall);
    write_run_files(&args.out, &run)?;
    if !args.quiet {
        println!("{}", serde_json::to_string_pretty(&run.summary)?);
        println!("results in {}", args.out.display());
    }
    Ok(())
}

/// `signorini run STUDY.toml`: the study's runs on every core, then `study.csv`,
/// `work_precision.svg` and `summary.json` (with the observed orders) in DIR.
fn run_study(args: &RunArgs, spec: &signorini_core::spec::JobSpec) -> Result<()> {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let quiet = args.quiet;
    let report = crate::study::run_study(spec, args.spec.parent(), threads, &|line| {
        if !quiet {
            eprintln!("{line}");
        }
    })
    .map_err(|e| anyhow!("study {}: {e:#}", args.spec.display()))?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    write_atomic(&args.out.join("study.csv"), &report.csv())?;
    for figure in signorini_figures::render(&[report.chart()]) {
        write_figure(&args.out, &figure)?;
    }
    let summary = serde_json::to_string_pretty(&report.summary())?;
    write_atomic(&args.out.join("summary.json"), &summary)?;
    if !quiet {
        println!("{summary}");
        println!("results in {}", args.out.display());
    }
    Ok(())
}
