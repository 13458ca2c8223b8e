//! Command-line interface: argument definitions and dispatch to one module per command.

pub mod check;
pub mod client;
mod compare;
mod lifecycle;
mod run;
mod schema;
pub mod serve;
mod solve;
mod watch_gaps;

use anyhow::Result;
use clap::{Parser, Subcommand};

/// Nonsmooth contact dynamics: Moreau–Jean, nonsmooth generalized-α, WFEM and SOI2
/// integrators with exact discrete energy bookkeeping.
#[derive(Debug, Parser)]
#[command(name = "signorini", version, propagate_version = true)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Run a job in this process (no server) and write its results to a directory.
    Run(run::RunArgs),
    /// Run the service: gRPC + HTTP API, worker pool, zenoh streams, SQLite store.
    Serve(Box<crate::config::ServeArgs>),
    /// Submit a job spec to a server; prints the job id.
    Submit(client::SubmitArgs),
    /// Print a job's status (state, progress) as JSON.
    Status(client::IdArgs),
    /// Follow a job live over zenoh: progress bar and energy terms (`--json` for machines).
    Watch(client::WatchArgs),
    /// Fetch a finished job's result (its summary, or with --out the files `run` writes).
    Result(client::ResultArgs),
    /// Cancel a queued, running or paused job.
    Cancel(client::IdArgs),
    /// Pause a job: a running one checkpoints after its next step and parks; `resume` goes on.
    Pause(client::IdArgs),
    /// Queue a paused job again; it continues from its checkpoint.
    Resume(client::IdArgs),
    /// Continue a succeeded job from its final state to a later `--t-end`, as a new job.
    Extend(lifecycle::ExtendArgs),
    /// List the runs of a study (a job with `[study]`), the reference run first.
    Children(client::ChildrenArgs),
    /// List jobs, newest first, one page at a time (`--state`, `--limit`, `--page-token`).
    List(client::ListArgs),
    /// Remove a finished job and its result from the server.
    Delete(client::IdArgs),
    /// List every scene, scheme and contact solver with parameters, defaults and ranges.
    Capabilities(client::CapabilitiesArgs),
    /// Print the JSON Schema of job specs (editors validate and complete spec files with it).
    Schema(schema::SchemaArgs),
    /// Compare finished runs (result directories): a figure per column, a table of summaries.
    Compare(compare::CompareArgs),
    /// The CI gate: run specs and check their [check] bounds (exit 0 hold, 1 fail, 2 bad spec).
    Check(check::CheckArgs),
    /// Solve one-step friction problem files (Siconos `.dat`, FCLib HDF5) with the FC3D solvers.
    Solve(solve::SolveArgs),
}

/// Runs the chosen subcommand.
pub fn dispatch(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Run(args) => run::run(args),
        Command::Serve(args) => serve::run(*args),
        Command::Submit(args) => client::submit(args),
        Command::Status(args) => client::status(args),
        Command::Watch(args) => client::watch(args),
        Command::Result(args) => client::result(args),
        Command::Cancel(args) => client::cancel(args),
        Command::Pause(args) => lifecycle::pause(args),
        Command::Resume(args) => lifecycle::resume(args),
        Command::Extend(args) => lifecycle::extend(args),
        Command::Children(args) => client::children(args),
        Command::List(args) => client::list(args),
        Command::Delete(args) => client::delete(args),
        Command::Capabilities(args) => client::capabilities(args),
        Command::Schema(args) => schema::schema(args),
        Command::Compare(args) => compare::compare(args),
        Command::Check(args) => check::check(args),
        Command::Solve(args) => solve::solve(args),
    }
}
