//! `pause`, `resume` and `extend`: a job's life after its submission, through the gRPC API
//! (`PauseJob`, `ResumeJob`, `ExtendJob`).

use super::client::{Connection, IdArgs, client, print_status, runtime, status_error, wait_ended};
use crate::proto::v1 as pb;
use anyhow::{Result, anyhow};
use clap::Args;

/// `signorini extend`.
#[derive(Debug, Args)]
pub struct ExtendArgs {
    /// The succeeded job to continue.
    pub id: String,
    /// The new final time, after the job's own.
    #[arg(long)]
    pub t_end: f64,
    /// Choose the new job's id (1–64 of A-Z a-z 0-9 _ -).
    #[arg(long)]
    pub new_id: Option<String>,
    /// Wait until the new job ends and print its final status (exit status 1 unless it
    /// succeeded).
    #[arg(long)]
    pub wait: bool,
    #[command(flatten)]
    pub conn: Connection,
}

/// `pause`: a running job checkpoints after its next step and parks, a queued one parks at
/// once; prints the status (`paused`).
pub fn pause(args: IdArgs) -> Result<()> {
    runtime()?.block_on(async {
        let mut c = client(&args.conn).await?;
        let req = pb::PauseJobRequest { id: args.id };
        let s = c.pause_job(req).await.map_err(status_error)?.into_inner();
        print_status(s)
    })
}

/// `resume`: queues a paused job again (it continues from its checkpoint); prints the status.
pub fn resume(args: IdArgs) -> Result<()> {
    runtime()?.block_on(async {
        let mut c = client(&args.conn).await?;
        let req = pb::ResumeJobRequest { id: args.id };
        let s = c.resume_job(req).await.map_err(status_error)?.into_inner();
        print_status(s)
    })
}

/// `extend`: a new job continuing a succeeded one from its final state to `--t-end`; prints
/// the new job's id, and with `--wait` its final status.
pub fn extend(args: ExtendArgs) -> Result<()> {
    if !args.t_end.is_finite() {
        return Err(anyhow!("--t-end {} is not a finite time", args.t_end));
    }
    runtime()?.block_on(async {
        let mut c = client(&args.conn).await?;
        let req = pb::ExtendJobRequest {
            id: args.id,
            t_end: args.t_end,
            new_id: args.new_id,
        };
        let id = c
            .extend_job(req)
            .await
            .map_err(status_error)?
            .into_inner()
            .id;
        println!("{id}");
        if args.wait {
            wait_ended(&mut c, &id).await?;
        }
        Ok(())
    })
}
