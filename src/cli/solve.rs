//! `signorini solve FILE… [--solver S] [--tolerance T] [--auto-sweeps N] [--warm-start] [--repeat N]
//! [--out DIR] [--json]` (docs/friction_benchmark.md): reads one-step friction problems (Siconos
//! `.dat`, FCLib HDF5), solves each with the core's FC3D solvers (planar problems embedded
//! exactly), prints per problem the contacts, the solver that answered, iterations, error and
//! time (with `--repeat N`, the fastest of N identical solves), and with `--out`
//! writes `DIR/NAME.hdf5` (FCLib layout: the local problem and `/solution/{r,u}`). With
//! `--warm-start` each solve starts from `FILE.start` (one number a line, as the rigid bench's
//! `--dump` writes the start a time step gave its solver) instead of r = 0.

use crate::problem_file::{self, RawProblem};
use anyhow::{Context, Result, bail};
use clap::Args;
use signorini_core::friction::{
    Fc3dError, Fc3dNewtonLinear, Fc3dOptions, Fc3dSolution, Fc3dSolverKind, Fc3dStall, solve_fc3d,
    solve_fc3d_from,
};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Arguments of `solve`.
#[derive(Debug, Args)]
pub struct SolveArgs {
    /// Problem files: Siconos `.dat` or FCLib HDF5 (local or global).
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// Solver: `auto` (Gauss–Seidel with Anderson acceleration, then the proximal point method),
    /// `nsgs`, `nsgs_aa` (Gauss–Seidel with Anderson acceleration), `nsn_ac` or `prox`.
    #[arg(long, default_value = "auto")]
    pub solver: String,
    /// Largest relative natural-map error accepted (Siconos' measure).
    #[arg(long, default_value_t = 1e-8)]
    pub tolerance: f64,
    /// Budget of sweeps or Newton iterations.
    #[arg(long, default_value_t = 10_000)]
    pub max_iterations: usize,
    /// Sweeps `auto`'s first stage (Gauss–Seidel with Anderson acceleration) runs before its
    /// proximal-point stage (a rigid time step gives 5 000).
    #[arg(long, default_value_t = Fc3dOptions::default().auto_sweeps)]
    pub auto_sweeps: usize,
    /// Over-relaxation ω ∈ (0, 2) of the plain Gauss–Seidel sweeps (`nsgs`, and those
    /// `nsgs_aa` and `auto` fall back to; a rigid time step gives 1.5).
    #[arg(long, default_value_t = Fc3dOptions::default().relaxation)]
    pub relaxation: f64,
    /// Stop Gauss–Seidel's sweeps (`nsgs`, `nsgs_aa`, `auto`'s sweeping stages) once this many
    /// in a row have not brought the smallest error below 0.9 times its value when they began
    /// (a rigid time step that accepts errors up to a bound gives 1 000); none by default.
    #[arg(long)]
    pub stall_sweeps: Option<usize>,
    /// ... only while the smallest error is at most this (a rigid time step gives its
    /// `contact_solver.accept_error`); at any error by default.
    #[arg(long, requires = "stall_sweeps")]
    pub stall_below: Option<f64>,
    /// Start each solve from `FILE.start` (3 × contacts numbers, one a line: the warm start the
    /// rigid bench's `--dump` writes next to the problem) instead of r = 0.
    #[arg(long)]
    pub warm_start: bool,
    /// Newton's linear systems: dense LU up to this many unknowns (3 × contacts), GMRES above.
    #[arg(long, default_value_t = Fc3dOptions::default().dense_newton_max)]
    pub dense_newton_max: usize,
    /// Newton's linear solve: `auto` (the sparse LU while its factors stay sparse, then the
    /// dense LU up to `--dense-newton-max` unknowns and GMRES above), `dense_lu`, `sparse_lu` or
    /// `gmres`.
    #[arg(long, default_value = "auto")]
    pub newton_linear: String,
    /// Solve each problem this many times (the solvers are deterministic: every solve takes
    /// the same path) and report the fastest time, as a time-stepping loop calls a solver whose
    /// code and memory are already warm; `seconds_first` keeps the first solve's time.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    pub repeat: u32,
    /// Write `DIR/NAME.hdf5` (the problem and FCLib's `/solution`) for each problem solved.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// One JSON line per problem instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// Runs `solve`. Exit status: an error when a file cannot be read or a problem is not solved
/// (after every file has been tried and reported).
pub fn solve(args: SolveArgs) -> Result<()> {
    let Some(kind) = Fc3dSolverKind::from_name(&args.solver) else {
        bail!(
            "--solver {}: unknown (auto, nsgs, nsgs_aa, nsn_ac or prox)",
            args.solver
        );
    };
    let Some(newton_linear) = Fc3dNewtonLinear::from_name(&args.newton_linear) else {
        bail!(
            "--newton-linear {}: unknown (auto, dense_lu, sparse_lu or gmres)",
            args.newton_linear
        );
    };
    if args.tolerance.is_nan() || args.tolerance <= 0.0 {
        bail!("--tolerance {}: must be > 0", args.tolerance);
    }
    let options = Fc3dOptions {
        kind,
        tolerance: args.tolerance,
        max_iterations: args.max_iterations,
        auto_sweeps: args.auto_sweeps,
        relaxation: args.relaxation,
        dense_newton_max: args.dense_newton_max,
        newton_linear,
        stall: args.stall_sweeps.map(|sweeps| Fc3dStall {
            sweeps,
            below: args.stall_below.unwrap_or(f64::INFINITY),
        }),
        ..Fc3dOptions::default()
    };
    options
        .check_relaxation()
        .map_err(|e| anyhow::anyhow!("--relaxation: {e}"))?;
    options
        .check_stall()
        .map_err(|e| anyhow::anyhow!("--stall-sweeps, --stall-below: {e}"))?;
    if args.out.is_some() && !cfg!(feature = "hdf5") {
        bail!(
            "--out writes FCLib HDF5 files: this signorini was built without HDF5; rebuild with \
             `cargo build --release --features hdf5` (needs the system libhdf5, Debian: libhdf5-dev)"
        );
    }
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    if !args.json {
        println!(
            "{:<40} {:>3} {:>8} {:>7} {:>6} {:>10} {:>10}",
            "file", "d", "contacts", "solver", "iters", "error", "seconds"
        );
    }
    let mut failures = Vec::new();
    for file in &args.files {
        let raw = match problem_file::read(file) {
            Ok(raw) => raw,
            Err(e) => {
                eprintln!("{e}");
                failures.push(e.to_string());
                continue;
            }
        };
        let problem = raw
            .to_fc3d()
            .with_context(|| format!("{}", file.display()))?;
        let start = if args.warm_start {
            match read_start(file) {
                Ok(start) => Some(start),
                Err(e) => {
                    eprintln!("{e:#}");
                    failures.push(format!("{e:#}"));
                    continue;
                }
            }
        } else {
            None
        };
        let solve_once = || {
            let clock = Instant::now();
            let outcome = match &start {
                Some(start) => solve_fc3d_from(&problem, &options, start),
                None => solve_fc3d(&problem, &options),
            };
            (outcome, clock.elapsed().as_secs_f64())
        };
        let (mut outcome, seconds_first) = solve_once();
        let mut seconds = seconds_first;
        for _ in 1..args.repeat {
            let (again, took) = solve_once();
            outcome = again;
            seconds = seconds.min(took);
        }
        let (converged, solver, iterations, error) = match &outcome {
            Ok(s) => (true, s.solver, s.iterations, s.error),
            Err(Fc3dError::NotConverged {
                solver,
                iterations,
                error,
                ..
            }) => (false, *solver, *iterations, *error),
            Err(e) => {
                let message = format!("{}: {e}", file.display());
                eprintln!("{message}");
                failures.push(message);
                continue;
            }
        };
        let name = file.display().to_string();
        if args.json {
            println!(
                "{}",
                serde_json::json!({
                    "file": name,
                    "dimension": raw.dimension,
                    "contacts": raw.contacts(),
                    "solver": solver,
                    "converged": converged,
                    "iterations": iterations,
                    "error": error,
                    "seconds": seconds,
                    "seconds_first": seconds_first,
                    "repeat": args.repeat,
                })
            );
        } else {
            println!(
                "{:<40} {:>3} {:>8} {:>7} {:>6} {:>10.3e} {:>10.4}{}",
                name,
                raw.dimension,
                raw.contacts(),
                solver,
                iterations,
                error,
                seconds,
                if converged { "" } else { "  not converged" }
            );
        }
        match outcome {
            Ok(s) => {
                if let Some(dir) = &args.out {
                    write_solution(dir, file, &raw, &s)?;
                }
            }
            Err(e) => failures.push(format!("{}: {e}", file.display())),
        }
    }
    if failures.is_empty() {
        Ok(())
    } else {
        bail!("{} of {} problems failed", failures.len(), args.files.len())
    }
}

/// The warm start of `file`: `FILE.start`, one number a line (its length is checked by the solve).
fn read_start(file: &Path) -> Result<Vec<f64>> {
    let mut path = file.as_os_str().to_owned();
    path.push(".start");
    let path = PathBuf::from(path);
    let text =
        std::fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
    text.lines()
        .enumerate()
        .filter(|(_, line)| !line.trim().is_empty())
        .map(|(k, line)| {
            line.trim()
                .parse::<f64>()
                .with_context(|| format!("{} line {}: not a number", path.display(), k + 1))
        })
        .collect()
}

/// Writes `DIR/NAME.hdf5`: the problem of `file` and FCLib's `/solution` (r, u; a planar
/// problem's own 2D components).
#[cfg(feature = "hdf5")]
fn write_solution(dir: &Path, file: &Path, raw: &RawProblem, s: &Fc3dSolution) -> Result<()> {
    let stem = file
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "problem".into());
    let stem = stem.strip_suffix(".hdf5").unwrap_or(&stem).to_string();
    let (r, u) = if raw.dimension == 2 {
        s.planar()
    } else {
        (s.r.clone(), s.u.clone())
    };
    let target = dir.join(format!("{stem}.hdf5"));
    problem_file::fclib::write_solution(&target, raw, &r, &u)
        .map_err(|e| anyhow::anyhow!("{}: {e}", target.display()))
}

/// Without HDF5 `solve` refuses `--out` before reading any file, so this is never reached.
#[cfg(not(feature = "hdf5"))]
fn write_solution(dir: &Path, _: &Path, _: &RawProblem, _: &Fc3dSolution) -> Result<()> {
    bail!(
        "{}: writing FCLib HDF5 needs the `hdf5` feature",
        dir.display()
    )
}
