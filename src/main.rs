//! `signorini`: nonsmooth contact dynamics from the command line, or as a service.

use clap::Parser;
use signorini::cli::Cli;
use std::process::ExitCode;

fn main() -> ExitCode {
    let cli = Cli::parse();
    match signorini::cli::dispatch(cli) {
        Ok(()) => ExitCode::SUCCESS,
        // `signorini check` ends with its own status (1 a bound failed, 2 a bad spec), its
        // verdict lines already printed.
        Err(e) => match e.downcast_ref::<signorini::cli::check::CheckExit>() {
            Some(exit) => ExitCode::from(exit.0),
            None => {
                eprintln!("error: {e:#}");
                ExitCode::FAILURE
            }
        },
    }
}
