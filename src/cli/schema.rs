//! `signorini schema`: the JSON Schema of job specs, for editors and other tools.

use anyhow::{Context, Result};
use clap::Args;
use std::path::PathBuf;

/// `signorini schema`.
#[derive(Debug, Args)]
pub struct SchemaArgs {
    /// Write the schema to this file instead of standard output.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// Prints (or writes) the JSON Schema of a job spec: every section, scene, scheme and analysis
/// with each field's description, default and range, generated from the spec types.
pub fn schema(args: SchemaArgs) -> Result<()> {
    let text = serde_json::to_string_pretty(&signorini_core::spec::json_schema())
        .context("serialising the schema")?;
    match args.out {
        Some(path) => std::fs::write(&path, text + "\n")
            .with_context(|| format!("writing {}", path.display())),
        None => {
            println!("{text}");
            Ok(())
        }
    }
}
