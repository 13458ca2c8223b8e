//! Command-line interface: argument definitions and dispatch to one module per command.

mod run;

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
}

/// Runs the chosen subcommand.
pub fn dispatch(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Run(args) => run::run(args),
    }
}
