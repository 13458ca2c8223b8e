//! Client commands: `submit`, `status`, `watch`, `result`, `cancel`, `list`, `children`, `delete`,
//! `capabilities`.
//! They talk gRPC to a running `signorini serve`; `watch` subscribes to the job's zenoh keys.

use super::watch_gaps::{Expected, KINDS};
use crate::output::{CsvSteps, FinishedRun, clear_results, write_run_files};
use crate::proto::encode::{status_from_proto, tables_from_proto};
use crate::proto::v1 as pb;
use crate::proto::v1::simulation_client::SimulationClient;
use crate::server::json::{FrameJson, StatusJson, status_with_lineage};
use crate::spec_file::{self, Format};
use crate::status::{JobView, Lineage};
use crate::stream::{self, ZenohOptions};
use anyhow::{Context, Result, anyhow};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use prost::Message;
use serde_json::json;
use signorini_core::observer::{Columns, Observer, StepRecord};
use signorini_figures::Figure;
use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use std::time::{Duration, Instant};
use tonic::transport::Channel;

/// Where the server is.
#[derive(Debug, Clone, Args)]
pub struct Connection {
    /// gRPC address of the server.
    #[arg(
        long,
        env = "SIGNORINI_SERVER",
        default_value = "http://127.0.0.1:50051",
        global = true
    )]
    pub server: String,
    /// Bearer token sent with every call: the shared token of `serve --token` (which the
    /// commands that change jobs need), or a per-client token of `serve --tokens FILE` (a read
    /// token for status, watch, result, list, …; a write token for everything).
    #[arg(long, env = "SIGNORINI_TOKEN", hide_env_values = true, global = true)]
    pub token: Option<String>,
    /// CA certificate (PEM) that signed the TLS certificate of a server started with
    /// `--tls-cert`: the connection is then TLS (`https://`; an `http://` server URL is taken as
    /// `https://`) and the server's certificate must be signed by it for the host of the URL.
    #[arg(long, env = "SIGNORINI_CA", global = true)]
    pub ca: Option<PathBuf>,
}

impl Connection {
    /// The gRPC channel to the server: plain for an `http://` URL, TLS verified against
    /// `--ca` with it (an `https://` URL needs `--ca`: no system roots are built in).
    pub async fn channel(&self) -> Result<Channel> {
        let url = match (&self.ca, self.server.strip_prefix("http://")) {
            (Some(_), Some(rest)) => format!("https://{rest}"),
            _ => self.server.clone(),
        };
        let mut endpoint = tonic::transport::Endpoint::from_shared(url.clone())
            .with_context(|| format!("--server {}", self.server))?;
        if url.starts_with("https://") {
            let ca = self.ca.as_ref().ok_or_else(|| {
                anyhow!(
                    "--server {}: an https:// server needs --ca FILE (the PEM certificate of the \
                     authority that signed the server's)",
                    self.server
                )
            })?;
            let pem =
                std::fs::read(ca).with_context(|| format!("reading --ca {}", ca.display()))?;
            endpoint = endpoint
                .tls_config(
                    tonic::transport::ClientTlsConfig::new()
                        .ca_certificate(tonic::transport::Certificate::from_pem(pem)),
                )
                .with_context(|| format!("--ca {}", ca.display()))?;
        }
        endpoint
            .connect()
            .await
            .with_context(|| format!("connecting to {url}"))
    }
}

/// `signorini submit`.
#[derive(Debug, Args)]
pub struct SubmitArgs {
    /// Job spec file (TOML, or JSON when it ends in .json).
    pub spec: PathBuf,
    /// Choose the job id (1–64 of A-Z a-z 0-9 _ -).
    #[arg(long)]
    pub id: Option<String>,
    /// Wait until the job ends and print its final status (exit status 1 unless it succeeded).
    #[arg(long, conflicts_with = "watch")]
    pub wait: bool,
    /// Follow the job live after submitting it, as `watch` does.
    #[arg(long)]
    pub watch: bool,
    /// zenoh endpoint for `--watch`.
    /// (`--zenoh-connect`, as for `serve`; `--zenoh` is its older spelling.)
    #[arg(
        long = "zenoh-connect",
        alias = "zenoh",
        env = "SIGNORINI_ZENOH_CONNECT",
        default_value = "tcp/127.0.0.1:7447"
    )]
    pub zenoh: String,
    #[command(flatten)]
    pub conn: Connection,
}

/// `signorini status` / `cancel` / `pause` / `resume` / `delete`.
#[derive(Debug, Args)]
pub struct IdArgs {
    /// Job id.
    pub id: String,
    #[command(flatten)]
    pub conn: Connection,
}

/// `signorini list`.
#[derive(Debug, Args)]
pub struct ListArgs {
    /// Only jobs in this state (queued, running, succeeded, failed, cancelled, paused).
    #[arg(long)]
    pub state: Option<String>,
    /// Most jobs to show (the server's default page is 100, its largest 1000).
    #[arg(long, default_value_t = 0)]
    pub limit: u32,
    /// Start after the page that printed this token (newest first).
    #[arg(long, default_value = "")]
    pub page_token: String,
    /// Print the page as JSON (`{"jobs": [status…], "next_page_token"}`).
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub conn: Connection,
}

/// `signorini children`.
#[derive(Debug, Args)]
pub struct ChildrenArgs {
    /// The study's (parent) job id.
    pub id: String,
    /// Print them as JSON (`{"jobs": [status…], "next_page_token": null}`).
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub conn: Connection,
}

/// `signorini result`.
#[derive(Debug, Args)]
pub struct ResultArgs {
    /// Job id.
    pub id: String,
    /// Write steps.csv, summary.json, tables (NAME.csv) and figures (NAME.svg) to this directory, as
    /// `signorini run` does.
    #[arg(long, short)]
    pub out: Option<PathBuf>,
    /// Only this column of the step series (repeat for several; all by default).
    #[arg(long = "column", short)]
    pub columns: Vec<String>,
    /// Only every N-th recorded row, and the last (all by default).
    #[arg(long, default_value_t = 1)]
    pub every: u64,
    #[command(flatten)]
    pub conn: Connection,
}

/// `signorini watch`.
#[derive(Debug, Args)]
pub struct WatchArgs {
    /// Job id.
    pub id: String,
    /// zenoh endpoint of the server's peer or of a router.
    /// (`--zenoh-connect`, as for `serve`; `--zenoh` is its older spelling.)
    #[arg(
        long = "zenoh-connect",
        alias = "zenoh",
        env = "SIGNORINI_ZENOH_CONNECT",
        default_value = "tcp/127.0.0.1:7447"
    )]
    pub zenoh: String,
    /// One JSON object per frame on stdout instead of a progress bar.
    #[arg(long)]
    pub json: bool,
    /// zenoh configuration file (JSON5): mode and credentials for a router with access control
    /// (deploy/zenoh/viewer.json5); --zenoh-connect replaces its endpoints.
    #[arg(long, env = "SIGNORINI_WATCH_ZENOH_CONFIG")]
    pub zenoh_config: Option<PathBuf>,
    /// The server whose gRPC API confirms the final status seen over zenoh.
    #[command(flatten)]
    pub conn: Connection,
}

/// `signorini capabilities`.
#[derive(Debug, Args)]
pub struct CapabilitiesArgs {
    /// Print this binary's own capabilities, offline (no server asked): the same answer a
    /// server of this version gives.
    #[arg(long)]
    pub local: bool,
    #[command(flatten)]
    pub conn: Connection,
}

/// Largest gRPC message accepted (results of long runs are large).
pub const MAX_MESSAGE: usize = 1 << 30;

pub(super) fn runtime() -> Result<tokio::runtime::Runtime> {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("starting tokio")
}

/// Adds `authorization: Bearer TOKEN` to every call when a token is given: reads need it too
/// on a server with `--tokens`.
#[derive(Clone)]
pub struct Bearer(Option<tonic::metadata::AsciiMetadataValue>);

impl tonic::service::Interceptor for Bearer {
    fn call(&mut self, mut req: tonic::Request<()>) -> Result<tonic::Request<()>, tonic::Status> {
        if let Some(value) = &self.0 {
            req.metadata_mut().insert("authorization", value.clone());
        }
        Ok(req)
    }
}

/// The gRPC client of the client commands: the channel of [`Connection::channel`], every call
/// carrying the token ([`Bearer`]).
pub type Api = SimulationClient<tonic::service::interceptor::InterceptedService<Channel, Bearer>>;

pub(super) async fn client(conn: &Connection) -> Result<Api> {
    let bearer =
        match &conn.token {
            Some(t) => Some(format!("Bearer {t}").parse().map_err(|_| {
                anyhow!("--token: not a valid header value (printable ASCII only)")
            })?),
            None => None,
        };
    let c = SimulationClient::with_interceptor(conn.channel().await?, Bearer(bearer));
    Ok(c.max_decoding_message_size(MAX_MESSAGE))
}

pub(super) fn status_error(s: tonic::Status) -> anyhow::Error {
    anyhow!("{:?}: {}", s.code(), s.message())
}

/// Prints a status as pretty JSON (the shape of `GET /v1/jobs/{id}`, with `parent` and
/// `extends` when `GetJob` set them).
pub(super) fn print_status(mut s: pb::JobStatus) -> Result<()> {
    let lineage = Lineage {
        parent: s.parent.take(),
        extends: s.extends.take(),
    };
    let view = status_from_proto(s)?;
    println!(
        "{}",
        serde_json::to_string_pretty(&status_with_lineage(&view, lineage))?
    );
    Ok(())
}

/// `submit`: prints the id; with `--wait`, then the final status; with `--watch`, then what
/// `watch` prints.
pub fn submit(args: SubmitArgs) -> Result<()> {
    let text = std::fs::read_to_string(&args.spec)
        .with_context(|| format!("reading {}", args.spec.display()))?;
    let spec = spec_file::parse(&text, Format::of_path(&args.spec))
        .map_err(|e| anyhow!("invalid spec {}: {e}", args.spec.display()))?;
    // Typed, as a gRPC client should; the sections the typed message does not carry
    // (`lagrangian` models, friction, [check], [study]) go as the JSON spelling.
    let typed = match crate::proto::typed_spec::job_spec_to_proto(&spec) {
        Ok(t) => pb::submit_job_request::Spec::Typed(t),
        Err(json_only) => {
            tracing::debug!("{json_only}");
            pb::submit_job_request::Spec::Json(serde_json::to_string(&spec)?)
        }
    };
    let id = runtime()?.block_on(async {
        let mut c = client(&args.conn).await?;
        let req = pb::SubmitJobRequest {
            spec: Some(typed),
            id: args.id.clone(),
        };
        let resp = c.submit_job(req).await.map_err(status_error)?;
        let id = resp.into_inner().id;
        println!("{id}");
        if args.wait {
            wait_ended(&mut c, &id).await?;
        }
        Ok::<_, anyhow::Error>(id)
    })?;
    if args.watch {
        return watch(WatchArgs {
            id,
            zenoh: args.zenoh,
            json: false,
            zenoh_config: None,
            conn: args.conn,
        });
    }
    Ok(())
}

/// Follows job `id` over `WatchJob` until it ends, prints its final status, and answers as
/// [`ended_ok`] (`submit --wait`, `extend --wait`).
pub(super) async fn wait_ended(c: &mut Api, id: &str) -> Result<()> {
    let mut frames = c
        .watch_job(pb::WatchJobRequest {
            id: id.to_string(),
            from_seq: None,
        })
        .await
        .map_err(status_error)?
        .into_inner();
    while let Some(frame) = frames.message().await.map_err(status_error)? {
        if let Some(pb::watch_frame::Frame::Status(s)) = frame.frame {
            let view = status_from_proto(s)?;
            if view.state.is_terminal() {
                println!(
                    "{}",
                    serde_json::to_string_pretty(&StatusJson::from(&view))?
                );
                return ended_ok(&view);
            }
        }
    }
    Err(anyhow!(
        "the server closed the stream of job {id} before it ended"
    ))
}

/// Ok for a succeeded job; an error with the state (and the reason of a failure) otherwise.
fn ended_ok(view: &JobView) -> Result<()> {
    match (&view.state, &view.error) {
        (crate::status::JobState::Succeeded, _) => Ok(()),
        (state, Some((field, reason))) => Err(anyhow!(
            "job {} {}: {field}: {reason}",
            view.id,
            state.as_str()
        )),
        (state, None) => Err(anyhow!("job {} {}", view.id, state.as_str())),
    }
}

/// `status`: prints the status as JSON.
pub fn status(args: IdArgs) -> Result<()> {
    runtime()?.block_on(async {
        let mut c = client(&args.conn).await?;
        let s = c
            .get_job(pb::GetJobRequest { id: args.id })
            .await
            .map_err(status_error)?
            .into_inner();
        print_status(s)
    })
}

/// `cancel`: prints the final status.
pub fn cancel(args: IdArgs) -> Result<()> {
    runtime()?.block_on(async {
        let mut c = client(&args.conn).await?;
        let req = pb::CancelJobRequest { id: args.id };
        let s = c.cancel_job(req).await.map_err(status_error)?.into_inner();
        print_status(s)
    })
}

/// `capabilities`: prints every scene, scheme and solver with its parameters as JSON.
/// With `--local`, this binary's own, without a server.
pub fn capabilities(args: CapabilitiesArgs) -> Result<()> {
    if args.local {
        return print_capabilities(&crate::server::convert::capabilities_to_proto(
            &signorini_core::capabilities::capabilities(),
        ));
    }
    runtime()?.block_on(async {
        let mut c = client(&args.conn).await?;
        let caps = c
            .capabilities(pb::CapabilitiesRequest {})
            .await
            .map_err(status_error)?
            .into_inner();
        print_capabilities(&caps)
    })
}

/// Prints capabilities as JSON: models, integrators, analyses, contact solvers and sections,
/// each with its parameters, and the scheme × feature table (`support`: per scheme and model
/// family, each feature taken, refused with its field and reason, or not in the model).
fn print_capabilities(caps: &pb::CapabilitiesResponse) -> Result<()> {
    let comp = |c: &pb::Component| {
        json!({
            "name": c.name,
            "description": c.description,
            "parameters": c.parameters.iter().map(|p| json!({
                "name": p.name, "kind": p.kind, "default": p.default_value, "range": p.range, "description": p.description
            })).collect::<Vec<_>>(),
        })
    };
    let out = json!({
        "models": caps.models.iter().map(comp).collect::<Vec<_>>(),
        "integrators": caps.integrators.iter().map(comp).collect::<Vec<_>>(),
        "analyses": caps.analyses.iter().map(comp).collect::<Vec<_>>(),
        "contact_solvers": caps.contact_solvers.iter().map(comp).collect::<Vec<_>>(),
        "sections": caps.sections.iter().map(comp).collect::<Vec<_>>(),
        "support": caps.support.iter().map(|row| json!({
            "scheme": row.scheme,
            "model": row.model,
            "features": row.features.iter().map(|f| json!({
                "feature": f.feature, "support": f.support, "field": f.field, "reason": f.reason
            })).collect::<Vec<_>>(),
        })).collect::<Vec<_>>(),
    });
    println!("{}", serde_json::to_string_pretty(&out)?);
    Ok(())
}

/// `list`: one page of jobs, newest first: `ID STATE PROGRESS NAME` per line (or JSON), and the
/// token of the next page on stderr when there is one.
pub fn list(args: ListArgs) -> Result<()> {
    let state = match args.state.as_deref() {
        None => pb::JobState::Unspecified,
        Some(s) => match crate::status::JobState::parse(s) {
            Some(st) => crate::proto::encode::state_to_proto(st),
            None => {
                return Err(anyhow!(
                    "--state {s:?} is not one of queued, running, succeeded, failed, cancelled, paused"
                ));
            }
        },
    };
    let page = runtime()?.block_on(async {
        let mut c = client(&args.conn).await?;
        c.list_jobs(pb::ListJobsRequest {
            limit: args.limit,
            page_token: args.page_token.clone(),
            state: state as i32,
        })
        .await
        .map_err(status_error)
        .map(tonic::Response::into_inner)
    })?;
    print_jobs(page.jobs, &page.next_page_token, args.json)?;
    if !args.json && !page.next_page_token.is_empty() {
        eprintln!("more: signorini list --page-token {}", page.next_page_token);
    }
    Ok(())
}

/// `children`: the runs of a study, in study order (the reference run first, if any), as
/// `list` prints a page.
pub fn children(args: ChildrenArgs) -> Result<()> {
    let jobs = runtime()?.block_on(async {
        let mut c = client(&args.conn).await?;
        c.list_children(pb::ListChildrenRequest { id: args.id })
            .await
            .map_err(status_error)
            .map(|r| r.into_inner().jobs)
    })?;
    print_jobs(jobs, "", args.json)
}

/// Prints jobs one per line (id, state, progress, name), or with `json` as
/// `{"jobs": [status…], "next_page_token"}` (null when `next` is empty).
fn print_jobs(jobs: Vec<pb::JobStatus>, next: &str, json: bool) -> Result<()> {
    let jobs = jobs
        .into_iter()
        .map(status_from_proto)
        .collect::<Result<Vec<_>>>()?;
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    let printed: Result<()> = (|| {
        if json {
            let jobs: Vec<StatusJson> = jobs.iter().map(StatusJson::from).collect();
            let next = (!next.is_empty()).then_some(next);
            writeln!(
                out,
                "{}",
                serde_json::to_string_pretty(&json!({ "jobs": jobs, "next_page_token": next }))?
            )?;
        } else {
            for j in &jobs {
                writeln!(
                    out,
                    "{}\t{}\t{:.1}%\t{}",
                    j.id,
                    j.state.as_str(),
                    100.0 * j.fraction(),
                    j.name.as_deref().unwrap_or("")
                )?;
            }
        }
        out.flush()?;
        Ok(())
    })();
    quiet_on_broken_pipe(printed)
}

/// `delete`: removes a finished job and its result from the server.
pub fn delete(args: IdArgs) -> Result<()> {
    runtime()?.block_on(async {
        let mut c = client(&args.conn).await?;
        let req = pb::DeleteJobRequest {
            id: args.id.clone(),
        };
        c.delete_job(req).await.map_err(status_error)?;
        println!("removed {}", args.id);
        Ok(())
    })
}

/// `result`: prints summary.json; with `--out DIR` writes the run's files there, as `run` does;
/// with `--column`/`--every` and no `--out` prints the cut series as CSV (the lines of
/// `steps.csv`). The result comes through `StreamResult` and goes to its file or stdout as it
/// arrives, so a result of any size needs a few MiB here. A failed or cancelled job's recorded
/// rows come too, with a warning on stderr that they are partial.
pub fn result(args: ResultArgs) -> Result<()> {
    use pb::result_chunk::Part;
    let cut_asked = !args.columns.is_empty() || args.every > 1;
    runtime()?.block_on(async {
        let mut c = client(&args.conn).await?;
        let mut stream = c
            .stream_result(pb::GetResultRequest {
                id: args.id.clone(),
                columns: args.columns.clone(),
                every: args.every,
                from_step: None,
                to_step: None,
            })
            .await
            .map_err(status_error)?
            .into_inner();
        let header = match stream.message().await.map_err(status_error)? {
            Some(pb::ResultChunk {
                part: Some(Part::Header(h)),
            }) => h,
            _ => return Err(anyhow!("the server sent no result header")),
        };
        let summary: serde_json::Map<String, serde_json::Value> =
            serde_json::from_str(&header.summary_json).context("summary from the server")?;
        if header.partial {
            let state = header
                .status
                .clone()
                .map(status_from_proto)
                .transpose()?
                .map_or("stopped", |v| v.state.as_str());
            eprintln!(
                "warning: job {} is {state}: {} rows it recorded before it stopped (a partial result)",
                args.id, header.rows
            );
        }
        let columns = Columns::new(header.columns.clone());
        let Some(dir) = &args.out else {
            if !cut_asked {
                println!("{}", serde_json::to_string_pretty(&summary)?);
                return Ok(());
            }
            let mut out = std::io::BufWriter::new(std::io::stdout().lock());
            let printed: Result<()> = async {
                writeln!(out, "step,t{}", header.columns.iter().map(|c| format!(",{c}")).collect::<String>())?;
                while let Some(msg) = stream.message().await.map_err(status_error)? {
                    if let Some(Part::Rows(rows)) = msg.part {
                        write_rows(&mut out, &rows, columns.names().len())?;
                    }
                }
                out.flush()?;
                Ok(())
            }
            .await;
            return quiet_on_broken_pipe(printed);
        };
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        clear_results(dir)?;
        // The files `signorini run` writes, by the same writers.
        let mut csv = CsvSteps::create(dir)?;
        let mut started = false;
        let mut figures = Vec::new();
        let n = header.columns.len();
        while let Some(msg) = stream.message().await.map_err(status_error)? {
            match msg.part {
                Some(Part::Figure(pb::Figure { name, svg })) => figures.push(Figure { name, svg }),
                Some(Part::Rows(rows)) => {
                    if !started {
                        csv.start(&columns);
                        started = true;
                    }
                    if rows.t.len() != rows.step.len() || rows.values.len() != rows.step.len() * n {
                        csv.discard();
                        return Err(anyhow!("the server sent a malformed chunk of rows"));
                    }
                    for (i, (&step, &t)) in rows.step.iter().zip(&rows.t).enumerate() {
                        let record = StepRecord {
                            step,
                            t,
                            values: &rows.values[i * n..(i + 1) * n],
                        };
                        if csv.observe(&record).is_break() {
                            break;
                        }
                    }
                }
                Some(Part::Header(_)) | None => {}
            }
        }
        if !started && n > 0 {
            // A series with columns and no row (a cut that keeps none) still gets its header.
            csv.start(&columns);
        }
        csv.finish()?;
        write_run_files(
            dir,
            &FinishedRun {
                summary,
                tables: tables_from_proto(header.tables),
                figures,
            },
        )?;
        println!("results of {} in {}", args.id, dir.display());
        Ok(())
    })
}

/// Writes rows of a `StreamResult` as CSV lines (the format of `steps.csv`).
fn write_rows(out: &mut impl Write, rows: &pb::ResultRows, n: usize) -> Result<()> {
    if rows.t.len() != rows.step.len() || rows.values.len() != rows.step.len() * n {
        return Err(anyhow!("the server sent a malformed chunk of rows"));
    }
    for (i, (&step, &t)) in rows.step.iter().zip(&rows.t).enumerate() {
        write!(out, "{step},{t:?}")?;
        for v in &rows.values[i * n..(i + 1) * n] {
            write!(out, ",{v:?}")?;
        }
        writeln!(out)?;
    }
    Ok(())
}

/// A reader that closed our stdout (`| head`) ends the command quietly and successfully.
fn quiet_on_broken_pipe(r: Result<()>) -> Result<()> {
    match r {
        Err(e)
            if e.chain().any(|c| {
                c.downcast_ref::<std::io::Error>()
                    .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
            }) =>
        {
            Ok(())
        }
        other => other,
    }
}

/// `watch`: follows a job's zenoh keys until it ends.
pub fn watch(args: WatchArgs) -> Result<()> {
    crate::engine::check_id(&args.id).map_err(|e| anyhow!("{e}"))?;
    runtime()?.block_on(async {
        let session = stream::open_session(&ZenohOptions {
            listen: Vec::new(),
            connect: vec![args.zenoh.clone()],
            config: args.zenoh_config.clone(),
        })
        .await?;
        let outcome = watch_session(&session, &args).await;
        let _ = session.close().await;
        let ended = async {
            let (shown, last) = outcome?;
            confirm(&args.conn, &last).await?;
            shown.end(&last)
        };
        // `watch … | head`: the reader has what it wanted.
        quiet_on_broken_pipe(ended.await)
    })
}

async fn query_status(session: &zenoh::Session, id: &str) -> Result<Option<JobView>> {
    let replies = session
        .get(stream::status_key(id))
        .await
        .map_err(|e| anyhow!("zenoh get: {e}"))?;
    let Ok(reply) = replies.recv_async().await else {
        return Ok(None);
    };
    match reply.result() {
        Ok(sample) => Ok(Some(decode_status(&sample.payload().to_bytes())?)),
        Err(e) => Err(anyhow!(
            "{}",
            String::from_utf8_lossy(&e.payload().to_bytes())
        )),
    }
}

/// A zenoh status frame.
fn decode_status(bytes: &[u8]) -> Result<JobView> {
    status_from_proto(pb::JobStatus::decode(bytes)?)
}

/// How `watch` shows a job: JSON lines (`--json`), a progress bar on a terminal, or one plain
/// line per status change and at most one a second otherwise (a log, a pipe).
enum Shown {
    Json,
    Bar(ProgressBar),
    Lines {
        last: Option<Instant>,
        state: Option<crate::status::JobState>,
        terms: String,
    },
}

impl Shown {
    fn new(json: bool) -> Shown {
        if json {
            return Shown::Json;
        }
        if !std::io::stdout().is_terminal() {
            return Shown::Lines {
                last: None,
                state: None,
                terms: String::new(),
            };
        }
        let bar = ProgressBar::new(1);
        bar.set_style(
            ProgressStyle::with_template("{bar:40} {pos}/{len} steps {msg}")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        Shown::Bar(bar)
    }

    /// Shows a status; true when it is final.
    fn status(&mut self, s: &JobView) -> Result<bool> {
        match self {
            Shown::Json => {
                let line = json!({ "kind": "status", "status": StatusJson::from(s) });
                writeln!(std::io::stdout().lock(), "{line}")?;
            }
            Shown::Bar(bar) => {
                bar.set_length(s.total.max(1));
                bar.set_position(s.done);
            }
            Shown::Lines { last, state, terms } => {
                let changed = *state != Some(s.state);
                if changed || last.is_none_or(|t| t.elapsed() >= Duration::from_secs(1)) {
                    writeln!(
                        std::io::stdout().lock(),
                        "{} {} step {}/{} ({:.1}%) t={:.6e}{}{terms}",
                        s.id,
                        s.state.as_str(),
                        s.done,
                        s.total,
                        100.0 * s.fraction(),
                        s.t,
                        if terms.is_empty() { "" } else { " " },
                    )?;
                    *last = Some(Instant::now());
                    *state = Some(s.state);
                }
            }
        }
        Ok(s.state.is_terminal())
    }

    /// Shows a step frame of `kind` (`energy` or `state`).
    fn frame(&mut self, kind: &str, f: &pb::StepFrame) -> Result<()> {
        if let Shown::Json = self {
            let json = FrameJson {
                kind,
                id: &f.id,
                seq: f.seq,
                columns: &f.columns,
                step: &f.step,
                t: &f.t,
                rows: FrameJson::rows(&f.values, f.columns.len()),
                last: f.last,
            };
            writeln!(
                std::io::stdout().lock(),
                "{}",
                serde_json::to_string(&json)?
            )?;
            return Ok(());
        }
        let n = f.columns.len().max(1);
        let (Some(row), Some(&step), "energy") = (f.values.chunks(n).last(), f.step.last(), kind)
        else {
            return Ok(());
        };
        let text: Vec<String> = f
            .columns
            .iter()
            .zip(row)
            .filter(|(c, _)| {
                matches!(
                    c.as_str(),
                    "kinetic" | "strain" | "energy" | "balance_residual"
                )
            })
            .map(|(c, v)| format!("{c}={v:.6e}"))
            .collect();
        match self {
            Shown::Bar(bar) => {
                bar.set_position(step);
                bar.set_message(text.join(" "));
            }
            Shown::Lines { last, terms, .. } => {
                *terms = text.join(" ");
                if last.is_none_or(|t| t.elapsed() >= Duration::from_secs(1)) {
                    let t = f.t.last().copied().unwrap_or_default();
                    writeln!(
                        std::io::stdout().lock(),
                        "{} running step {step} t={t:.6e} {terms}",
                        f.id
                    )?;
                    *last = Some(Instant::now());
                }
            }
            Shown::Json => {}
        }
        Ok(())
    }

    /// The end: the bar goes, and (but for JSON lines) the final status is printed in full.
    fn end(&self, s: &JobView) -> Result<()> {
        match self {
            Shown::Json => return Ok(()),
            Shown::Bar(bar) => bar.finish_and_clear(),
            Shown::Lines { .. } => {}
        }
        writeln!(
            std::io::stdout().lock(),
            "{}",
            serde_json::to_string_pretty(&StatusJson::from(s))?
        )?;
        Ok(())
    }
}

/// Checks a final status seen over zenoh against the server's gRPC API, which only the server
/// answers: a different state is an error (a frame published by someone else, or stale). When
/// the API cannot be reached the status stands, with a warning that it is unconfirmed.
async fn confirm(conn: &Connection, seen: &JobView) -> Result<()> {
    let asked = async {
        let mut c = client(conn).await?;
        let s = c
            .get_job(pb::GetJobRequest {
                id: seen.id.clone(),
            })
            .await
            .map_err(status_error)?;
        status_from_proto(s.into_inner())
    };
    match asked.await {
        Ok(server) if server.state == seen.state => Ok(()),
        Ok(server) => Err(anyhow!(
            "zenoh said job {} is {}, but the server at {} says {}: that status was not the server's",
            seen.id,
            seen.state.as_str(),
            conn.server,
            server.state.as_str()
        )),
        Err(e) => {
            eprintln!(
                "warning: the final status of job {} is unconfirmed (no answer from {}: {e:#})",
                seen.id, conn.server
            );
            Ok(())
        }
    }
}

/// Live samples `watch` holds unread at most: past them the oldest are dropped (their frames
/// are then fetched from the history), so zenoh never waits on `watch`.
const LIVE_SAMPLES: usize = 256;

async fn watch_session(session: &zenoh::Session, args: &WatchArgs) -> Result<(Shown, JobView)> {
    let key = format!("signorini/v1/jobs/{}/*", args.id);
    // A ring, not zenoh's default queue, which blocks the session's reading when full: while
    // `watch` fetches frames from the history it reads no live sample, a server publishing its
    // backlog (frames held up by a silent subscriber) filled the queue, zenoh stopped reading
    // the link, and the server closed it after 5 s with the history's replies in it (the fetch
    // then ended in a timeout, and the job's last frames were missing).
    let sub = session
        .declare_subscriber(key)
        .with(zenoh::handlers::RingChannel::new(LIVE_SAMPLES))
        .await
        .map_err(|e| anyhow!("zenoh subscribe: {e}"))?;
    let mut shown = Shown::new(args.json);
    // The latest status (the query also makes sure our subscription is known to the server).
    let mut tries = 0;
    let current = loop {
        match query_status(session, &args.id).await {
            Ok(Some(s)) => break s,
            Ok(None) if tries < 50 => {
                tries += 1;
                tokio::time::sleep(Duration::from_millis(100)).await;
            }
            Ok(None) => return Err(anyhow!("no signorini server answered on {}", args.zenoh)),
            Err(e) => return Err(e),
        }
    };
    if shown.status(&current)? {
        return Ok((shown, current));
    }
    let mut expected = Expected::default();
    let last_status = loop {
        let sample = match tokio::time::timeout(Duration::from_secs(2), sub.recv_async()).await {
            Ok(Ok(s)) => s,
            Ok(Err(e)) => return Err(anyhow!("zenoh: {e}")),
            Err(_) => {
                // Quiet for a while: ask (a final status may have been missed).
                match query_status(session, &args.id).await? {
                    Some(s) if s.state.is_terminal() => break s,
                    Some(s) => {
                        shown.status(&s)?;
                    }
                    None => {}
                }
                continue;
            }
        };
        let key = sample.key_expr().as_str().to_string();
        let bytes = sample.payload().to_bytes();
        if key.ends_with("/status") {
            let s = decode_status(&bytes)?;
            if s.state.is_terminal() {
                break s;
            }
            shown.status(&s)?;
        } else {
            let k = usize::from(!key.ends_with("/energy"));
            let f = pb::StepFrame::decode(&*bytes)?;
            for f in expected.live(session, &args.id, k, f).await? {
                shown.frame(KINDS[k], &f)?;
            }
        }
    };
    // The frames after the last one seen live (lost while a router was down, or dropped), then
    // the end: frames that cannot be fetched are an error, not a hole in the output.
    for (k, kind) in KINDS.iter().enumerate() {
        let frames = expected
            .rest(session, &args.id, k)
            .await
            .with_context(|| format!("the last {kind} frames of job {}", args.id))?;
        for f in frames {
            shown.frame(kind, &f)?;
        }
    }
    // Nothing live is read after the end. The subscription goes only now: undeclared just
    // before the history queries, it raced them in zenoh 1.10.2 — the server got a query
    // naming the key-expression resource being undeclared ("Received Query for unknown
    // key_expr: Remote resource 4 not found"), dropped it without a final reply, and the
    // query timed out (one run in twelve of tests/cli_service.rs on this machine).
    if let Err(e) = sub.undeclare().await {
        tracing::debug!("zenoh undeclare: {e}");
    }
    shown.status(&last_status)?;
    Ok((shown, last_status))
}
