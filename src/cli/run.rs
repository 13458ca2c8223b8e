//! `signorini run SPEC --out DIR`: validate a spec, run it in-process, write the results.

use crate::config::Limits;
use crate::output::{
    CHECKPOINT_FILE, CsvSteps, RUN_SPEC_FILE, clear_checkpoint, clear_results, finish_run,
    write_atomic, write_checkpoint, write_figure, write_run_files,
};
use crate::spec_file::{self, Format};
use crate::vtk::{StepSeries, write_rigid_vtk};
use anyhow::{Context, Result, anyhow};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use signorini_core::checkpoint::Checkpoint;
use signorini_core::job::{self, Job};
use signorini_core::lagrangian::StartProjection;
use signorini_core::observer::{Columns, Observer, Progress, StepRecord};
use signorini_core::outcome::RunOutput;
use signorini_core::spec::{CheckpointPeriod, ModelSpec};
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Arguments of `signorini run`.
#[derive(Debug, Args)]
#[command(after_help = "\
The spec is TOML (or JSON if the file ends in .json) with the sections
[model] (scene = bouncing_ball | bar | dep_bar | chain | linear …), [integrator] (scheme = moreau_jean …),
[time] (h, t_end or steps), [contact_solver], [output] (every, probes). Examples: examples/*.toml

Writes DIR/steps.csv (step, t, energy terms, gap/u/p per contact, q/v per probe) and
DIR/summary.json (steps, wall_s, steps_per_s, max_abs_balance_residual, energies, impacts, …).
While a time integration runs, DIR/checkpoint.bin is rewritten every output.checkpoint_seconds
(default 30) and/or output.checkpoint_steps; `run --resume DIR` continues an interrupted run
to the same steps.csv and summary.json as an uninterrupted one (bit for bit, wall time aside).

  signorini run examples/bouncing_ball.toml --out out/ball
  signorini run --resume out/ball")]
pub struct RunArgs {
    /// Job spec file (TOML, or JSON when it ends in .json).
    #[arg(required_unless_present = "resume", conflicts_with = "resume")]
    pub spec: Option<PathBuf>,
    /// Directory for steps.csv and summary.json (created if missing).
    #[arg(long, short, default_value = "out")]
    pub out: PathBuf,
    /// Continue the interrupted run whose results go to DIR, from DIR/checkpoint.bin (a missing
    /// or damaged checkpoint: the run starts again from step 0, and says so).
    #[arg(long, value_name = "DIR")]
    pub resume: Option<PathBuf>,
    /// No progress bar and no summary on stdout.
    #[arg(long, short)]
    pub quiet: bool,
    /// Run a job larger than a server accepts by default (more than 10⁸ steps or about 1 GiB
    /// of recorded output): without it such a spec is refused naming the field, as the server
    /// refuses it.
    #[arg(long)]
    pub no_limits: bool,
}

/// Writes the checkpoints of a run to its directory at the spec's period.
struct Checkpointer {
    dir: PathBuf,
    period: CheckpointPeriod,
    last: Instant,
}

/// Writes rows to steps.csv, checkpoints to checkpoint.bin, and drives a progress bar.
struct CliObserver {
    csv: CsvSteps,
    bar: ProgressBar,
    last_draw: Instant,
    checkpoints: Option<Checkpointer>,
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

    fn checkpoint_due(&mut self, p: Progress) -> bool {
        let Some(c) = &self.checkpoints else {
            return false;
        };
        // The clock is read every 16th step only: the check stays far below a step's cost.
        c.period.steps.is_some_and(|n| p.done.is_multiple_of(n))
            || (p.done.is_multiple_of(16) && c.last.elapsed().as_secs_f64() >= c.period.seconds)
    }

    fn checkpoint(&mut self, checkpoint: &mut Checkpoint) {
        let Some(c) = &mut self.checkpoints else {
            return;
        };
        c.last = Instant::now();
        // The rows the checkpoint counts reach the disk before the checkpoint does.
        let written = self.csv.sync().and_then(|()| {
            let bytes = checkpoint.encode()?;
            write_checkpoint(&c.dir, &bytes)
        });
        if let Err(e) = written {
            self.bar
                .suspend(|| eprintln!("signorini: checkpoint not written: {e:#}"));
        }
    }
}

/// Runs the command.
pub fn run(args: RunArgs) -> Result<()> {
    if let Some(dir) = &args.resume {
        return resume(dir, args.quiet);
    }
    let Some(spec_path) = &args.spec else {
        return Err(anyhow!("give a spec file, or --resume DIR"));
    };
    // DIR holds the results of the last run or nothing: stale results go first, so a refused
    // spec or a failed run cannot leave files that look valid.
    if args.out.is_dir() {
        clear_results(&args.out)?;
        clear_checkpoint(&args.out)?;
    }
    let text = std::fs::read_to_string(spec_path)
        .with_context(|| format!("reading {}", spec_path.display()))?;
    let spec = spec_file::parse(&text, Format::of_path(spec_path))
        .map_err(|e| anyhow!("invalid spec {}: {e}", spec_path.display()))?;
    if spec.study.is_some() {
        return run_study(&args, spec_path, &spec);
    }
    let job =
        Job::from_spec(&spec).map_err(|e| anyhow!("invalid spec {}: {e}", spec_path.display()))?;
    if !args.no_limits {
        crate::engine::check_limits(&job, &Limits::DEFAULT).map_err(|e| {
            anyhow!(
                "invalid spec {}: {e} (the server's default limits; `run --no-limits` lifts them)",
                spec_path.display()
            )
        })?;
    }
    if let Some(p) = job.start_projection() {
        eprintln!("{}", projection_note(p));
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    if job.checkpoints() {
        write_atomic(
            &args.out.join(RUN_SPEC_FILE),
            &serde_json::to_string_pretty(&spec)?,
        )?;
    }
    let csv = CsvSteps::create(&args.out)?;
    execute(&job, &args.out, csv, None, args.quiet)
}

/// The note `run` prints when a model's start was moved onto its joints: the values the run
/// starts from, against those given (`start_projection` in summary.json has them all).
fn projection_note(p: &StartProjection) -> String {
    format!(
        "signorini: note: q0 and v0 were projected onto the joints (model.project_onto_joints, {} Newton iterations, joint residual {:e} -> {:e}):\n  q0 = {:?} (given {:?})\n  v0 = {:?} (given {:?})\n  the run starts there; summary.json has them as start_projection",
        p.newton_iterations,
        p.joint_residual_given,
        p.joint_residual,
        p.q0,
        p.q0_given,
        p.v0,
        p.v0_given
    )
}

/// `signorini run --resume DIR`: continues the run of DIR/run_spec.json from DIR/checkpoint.bin;
/// a checkpoint that is missing or cannot be used (damaged, of another spec or version) is
/// reported and the run starts again from step 0.
fn resume(dir: &Path, quiet: bool) -> Result<()> {
    let spec_path = dir.join(RUN_SPEC_FILE);
    let text = std::fs::read_to_string(&spec_path).with_context(|| {
        format!(
            "reading {} (is {} the --out of an interrupted run?)",
            spec_path.display(),
            dir.display()
        )
    })?;
    let spec = spec_file::parse(&text, Format::Json)
        .map_err(|e| anyhow!("invalid spec {}: {e}", spec_path.display()))?;
    let job =
        Job::from_spec(&spec).map_err(|e| anyhow!("invalid spec {}: {e}", spec_path.display()))?;
    let usable = std::fs::read(dir.join(CHECKPOINT_FILE))
        .map_err(anyhow::Error::from)
        .and_then(|bytes| Ok(job.read_checkpoint(&bytes)?))
        .and_then(|c| {
            let csv = CsvSteps::resume(dir, c.records())?;
            Ok((c, csv))
        });
    match usable {
        Ok((checkpoint, csv)) => {
            if !quiet {
                eprintln!(
                    "signorini: resuming {} after step {}",
                    dir.display(),
                    checkpoint.step()
                );
            }
            execute(&job, dir, csv, Some(checkpoint), quiet)
        }
        Err(e) => {
            eprintln!(
                "signorini: the checkpoint in {} cannot be used ({e:#}): rerunning from step 0",
                dir.display()
            );
            clear_results(dir)?;
            let csv = CsvSteps::create(dir)?;
            execute(&job, dir, csv, None, quiet)
        }
    }
}

/// Runs `job` (from the start, or from `checkpoint`) into `out`, checkpointing at the spec's
/// period, and writes the result files; the checkpoint goes once the results are complete.
fn execute(
    job: &Job,
    out: &Path,
    csv: CsvSteps,
    checkpoint: Option<Checkpoint>,
    quiet: bool,
) -> Result<()> {
    let bar = if quiet {
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
    let period = job.spec().output.checkpoint_period()?;
    let mut observer = CliObserver {
        csv,
        bar,
        last_draw: Instant::now(),
        checkpoints: job.checkpoints().then(|| Checkpointer {
            dir: out.to_path_buf(),
            period,
            last: Instant::now(),
        }),
    };
    let started = Instant::now();
    // The CLI runs one job: it may use every core for an analysis's parallel scans.
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let result = job::run_with_detectors(
        job,
        threads,
        &mut observer,
        checkpoint.as_ref(),
        &signorini_collision::ParryDetectors,
    );
    let wall = started.elapsed();
    observer.bar.finish_and_clear();
    let output: RunOutput = match result {
        Ok(o) => o,
        Err(e) => {
            // The rows up to the failure stay (as the server keeps them), and summary.json
            // says why the run stopped.
            let kept = observer.csv.finish();
            let summary = serde_json::json!({
                "status": "failed",
                "error": e.to_string(),
                "wall_s": wall.as_secs_f64(),
            });
            write_atomic(
                &out.join("summary.json"),
                &serde_json::to_string_pretty(&summary)?,
            )?;
            kept?;
            return Err(anyhow!(
                "run failed: {e} (the steps recorded so far are in {})",
                out.join("steps.csv").display()
            ));
        }
    };
    observer.csv.finish()?;
    if job.spec().output.vtk {
        write_vtk(job, out, &output)?;
    }
    let run = finish_run(output, wall);
    write_run_files(out, &run)?;
    clear_checkpoint(out)?;
    if !quiet {
        println!("{}", serde_json::to_string_pretty(&run.summary)?);
        println!("results in {}", out.display());
    }
    Ok(())
}

/// `output.vtk = true`: the ParaView files of a rigid run, from its `steps.csv` and its
/// `contacts` table ([`crate::vtk`]).
fn write_vtk(job: &Job, out: &Path, output: &RunOutput) -> Result<()> {
    let spec = job.spec();
    let Some(ModelSpec::RigidBodies(rigid)) = &spec.model else {
        return Err(anyhow!(
            "output.vtk: only a rigid_bodies job writes VTK files"
        ));
    };
    let scene = rigid.validate()?;
    let h = spec.time_section()?.h;
    let steps = StepSeries::read_csv(&out.join("steps.csv"))?;
    let contacts = output.tables.iter().find(|t| t.name == "contacts");
    write_rigid_vtk(out, &scene, h, &steps, contacts)
}

/// `signorini run STUDY.toml`: the study's runs on every core, then `study.csv`,
/// `work_precision.svg` and `summary.json` (with the observed orders) in DIR.
fn run_study(args: &RunArgs, spec_path: &Path, spec: &signorini_core::spec::JobSpec) -> Result<()> {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let quiet = args.quiet;
    let report = crate::study::run_study(spec, spec_path.parent(), threads, &|line| {
        if !quiet {
            eprintln!("{line}");
        }
    })
    .map_err(|e| anyhow!("study {}: {e:#}", spec_path.display()))?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let outputs = crate::study::outputs(&report)?;
    write_atomic(&args.out.join("study.csv"), &outputs.csv)?;
    for figure in &outputs.figures {
        write_figure(&args.out, figure)?;
    }
    let summary = serde_json::to_string_pretty(&outputs.summary)?;
    write_atomic(&args.out.join("summary.json"), &summary)?;
    if !quiet {
        println!("{summary}");
        println!("results in {}", args.out.display());
    }
    Ok(())
}
