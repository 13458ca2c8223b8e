//! `signorini serve`: runs the service (see `signorini serve --help`).

use crate::config::{ServeArgs, ServeConfig};
use crate::store::Location;
use anyhow::{Context, Result};
use std::io::IsTerminal;

/// Runs the command: a multi-threaded tokio runtime (zenoh needs it) for the listeners; jobs run
/// on the engine's own threads.
pub fn run(args: ServeArgs) -> Result<()> {
    let _ = tracing_subscriber::fmt()
        .with_writer(std::io::stderr)
        .with_target(false)
        // Colour codes only for a terminal: a log file or a journal gets plain text.
        .with_ansi(std::io::stderr().is_terminal())
        .try_init();
    let cfg = ServeConfig::resolve(args)?;
    // A SQLite store's directory (the data directory by default) is made on first start.
    if let Location::Sqlite(path) = Location::of(&cfg.store)
        && let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty())
    {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("starting the tokio runtime")?;
    let served = runtime.block_on(crate::server::serve(cfg));
    // A blocking task still running (a request's work the shutdown abandoned) does not hold
    // the process: it ends with it.
    runtime.shutdown_timeout(std::time::Duration::from_secs(1));
    served
}
