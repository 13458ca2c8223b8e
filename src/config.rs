//! `signorini serve` configuration: defaults, then an optional TOML file (`--config`), then
//! environment variables (`SIGNORINI_*`), then flags — each layer overrides the one before.

use anyhow::{Context, Result, bail};
use clap::Args;
use serde::Deserialize;
use std::net::SocketAddr;
use std::path::PathBuf;

/// Flags of `signorini serve` (each also read from the environment variable shown).
#[derive(Debug, Clone, Default, Args)]
#[command(after_help = "\
Configuration layers: built-in defaults < TOML file (--config) < environment < flags.
The TOML file uses the flag names with underscores, e.g.

  grpc_addr = \"127.0.0.1:50051\"
  http_addr = \"127.0.0.1:8080\"
  data_dir = \"signorini-data\"     # the default store is DATA_DIR/signorini.db
  store = \"signorini-data/signorini.db\"   # or \"postgres://user@host/db\": replicas share it
  store_max_mb = 4096             # SQLite: the store's largest size (writes past it are refused)
  replica = \"node-a\"              # with PostgreSQL: this replica's name (default: host-pid-random)
  lease_secs = 10.0               # with PostgreSQL: a job's lease, renewed by the heartbeat
  zenoh_listen = [\"tcp/127.0.0.1:7447\"]
  zenoh_connect = []            # e.g. [\"tcp/zenohd:7447\"] to join a zenoh router
  zenoh_config = \"deploy/zenoh/service.json5\"   # optional: mode, authentication, ACL
  workers = 4
  queue_limit = 256
  token = \"secret\"              # bearer token required by mutating calls (submit, cancel)
  tokens = \"tokens.toml\"        # or: per-client tokens with scopes ([[token]] name, scope, sha256)
  tls_cert = \"cert.pem\"         # with tls_key: both listeners speak TLS only (PEM files)
  tls_key = \"key.pem\"
  max_dofs = 100000
  max_steps = 100000000
  max_output_mb = 1024
  max_memory_mb = 2048          # a job's memory: estimated before it is compiled, watched while it runs
  max_compile_seconds = 30      # compiling a job's model (a `lagrangian` one: its symbolic derivatives)
  max_wall_seconds = 86400      # a job's run (unlimited by default)
  retain_days = 30              # remove finished jobs 30 days after they ended (default: keep)

HTTP: POST /v1/jobs, GET /v1/jobs?limit=&state=&page_token=, GET /v1/jobs/{id},
GET /v1/jobs/{id}/result?format=json|csv|npz&columns=&every=&from=&to= (streamed, gzip),
GET /v1/jobs/{id}/events?from_seq= (SSE), GET /v1/jobs/{id}/figures, GET /v1/jobs/{id}/figures/{name}
(SVG), DELETE /v1/jobs/{id}[?purge=true], GET /v1/capabilities, GET /healthz, GET /metrics,
GET / (jobs), GET /jobs/{id} (live page).
gRPC: signorini.v1.Simulation and grpc.health.v1.Health.
zenoh: signorini/v1/jobs/{id}/status, …/state, …/energy (protobuf frames); get …/energy/* and
…/state/* for the recorded frames.")]
pub struct ServeArgs {
    /// TOML configuration file.
    #[arg(long, env = "SIGNORINI_CONFIG")]
    pub config: Option<PathBuf>,
    /// gRPC listen address [default: 127.0.0.1:50051].
    #[arg(long, env = "SIGNORINI_GRPC_ADDR")]
    pub grpc_addr: Option<SocketAddr>,
    /// HTTP listen address [default: 127.0.0.1:8080].
    #[arg(long, env = "SIGNORINI_HTTP_ADDR")]
    pub http_addr: Option<SocketAddr>,
    /// SQLite store file, or a PostgreSQL URL (`postgres://user:password@host:5432/db`) that
    /// any number of replicas share, with the queue [default: DATA_DIR/signorini.db].
    #[arg(long, env = "SIGNORINI_STORE")]
    pub store: Option<PathBuf>,
    /// With a SQLite store: its largest size in MiB (SQLite's `max_page_count`); a write past
    /// it is refused as on a full disk: the job fails naming it, `/healthz` reports the store
    /// degraded and submissions are refused until there is room (no limit by default).
    #[arg(long, env = "SIGNORINI_STORE_MAX_MB")]
    pub store_max_mb: Option<u64>,
    /// Directory of the server's own files when `--store` does not name them: the SQLite store
    /// `signorini.db` (created with the directory) [default: signorini-data].
    #[arg(long, env = "SIGNORINI_DATA_DIR")]
    pub data_dir: Option<PathBuf>,
    /// This replica's name in a PostgreSQL store's claims; unique among the replicas
    /// [default: HOSTNAME-PID-RANDOM].
    #[arg(long, env = "SIGNORINI_REPLICA")]
    pub replica: Option<String>,
    /// With a PostgreSQL store: seconds a claimed job stays this replica's without a heartbeat
    /// (renewed four times per lease); a replica that dies gives its jobs up after this long
    /// [default: 10].
    #[arg(long, env = "SIGNORINI_LEASE_SECS")]
    pub lease_secs: Option<f64>,
    /// zenoh endpoint(s) the embedded peer listens on [default: tcp/127.0.0.1:7447].
    #[arg(long, env = "SIGNORINI_ZENOH_LISTEN", value_delimiter = ',')]
    pub zenoh_listen: Vec<String>,
    /// zenoh router or peer endpoint(s) to connect to (none by default).
    #[arg(long, env = "SIGNORINI_ZENOH_CONNECT", value_delimiter = ',')]
    pub zenoh_connect: Vec<String>,
    /// zenoh configuration file (JSON5) for the service's session: mode, authentication and
    /// access control (deploy/zenoh/); --zenoh-listen/--zenoh-connect replace its endpoints.
    #[arg(long, env = "SIGNORINI_ZENOH_CONFIG")]
    pub zenoh_config: Option<PathBuf>,
    /// Worker threads [default: number of cores].
    #[arg(long, env = "SIGNORINI_WORKERS")]
    pub workers: Option<usize>,
    /// Most jobs waiting in the queue; more are refused (429 / RESOURCE_EXHAUSTED) [default: 256].
    #[arg(long, env = "SIGNORINI_QUEUE_LIMIT")]
    pub queue_limit: Option<usize>,
    /// Bearer token required by mutating calls (none by default; health and reads stay open).
    #[arg(long, env = "SIGNORINI_TOKEN", hide_env_values = true)]
    pub token: Option<String>,
    /// Per-client bearer tokens: a TOML file of `[[token]]` tables `{ name, scope = "read" |
    /// "write", sha256 = "hex of the token" }`; every call but /healthz then needs one (401
    /// without, 403 for a read token on a mutating call). Not with --token.
    #[arg(long, env = "SIGNORINI_TOKENS")]
    pub tokens: Option<PathBuf>,
    /// TLS certificate chain (PEM, leaf first); with --tls-key, the gRPC and HTTP listeners
    /// speak TLS only and clients connect with `https://` and `--ca` (none by default).
    #[arg(long, env = "SIGNORINI_TLS_CERT")]
    pub tls_cert: Option<PathBuf>,
    /// The private key of --tls-cert (PEM: PKCS#8, PKCS#1 or SEC1).
    #[arg(long, env = "SIGNORINI_TLS_KEY")]
    pub tls_key: Option<PathBuf>,
    /// Largest model accepted, in degrees of freedom [default: 100000].
    #[arg(long, env = "SIGNORINI_MAX_DOFS")]
    pub max_dofs: Option<u64>,
    /// Most time steps per job [default: 100000000].
    #[arg(long, env = "SIGNORINI_MAX_STEPS")]
    pub max_steps: Option<u64>,
    /// Remove finished jobs and their results this many days after they ended (fractions
    /// allowed; kept forever by default).
    #[arg(long, env = "SIGNORINI_RETAIN_DAYS")]
    pub retain_days: Option<f64>,
    /// Largest estimated recorded output per job, in MiB [default: 1024].
    #[arg(long, env = "SIGNORINI_MAX_OUTPUT_MB")]
    pub max_output_mb: Option<u64>,
    /// Largest memory a job may need, in MiB, estimated from its model's sizes before its model
    /// is compiled (a larger job is refused naming the limit) and watched while it runs (a run
    /// holding more ends `failed` naming the limit) [default: 2048].
    #[arg(long, env = "SIGNORINI_MAX_MEMORY_MB")]
    pub max_memory_mb: Option<u64>,
    /// Longest a submission may spend compiling its model (a `lagrangian` model's symbolic
    /// derivatives and tapes), in seconds; past it the submission is refused naming the limit
    /// [default: 30].
    #[arg(long, env = "SIGNORINI_MAX_COMPILE_SECONDS")]
    pub max_compile_seconds: Option<f64>,
    /// Longest a job may run, in seconds of wall time; past it the job ends `failed` naming the
    /// limit (unlimited by default).
    #[arg(long, env = "SIGNORINI_MAX_WALL_SECONDS")]
    pub max_wall_seconds: Option<f64>,
}

/// The `--config` file.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct FileConfig {
    grpc_addr: Option<SocketAddr>,
    http_addr: Option<SocketAddr>,
    store: Option<PathBuf>,
    store_max_mb: Option<u64>,
    data_dir: Option<PathBuf>,
    replica: Option<String>,
    lease_secs: Option<f64>,
    zenoh_listen: Option<Vec<String>>,
    zenoh_connect: Option<Vec<String>>,
    zenoh_config: Option<PathBuf>,
    workers: Option<usize>,
    queue_limit: Option<usize>,
    token: Option<String>,
    tokens: Option<PathBuf>,
    tls_cert: Option<PathBuf>,
    tls_key: Option<PathBuf>,
    max_dofs: Option<u64>,
    max_steps: Option<u64>,
    max_output_mb: Option<u64>,
    max_memory_mb: Option<u64>,
    max_compile_seconds: Option<f64>,
    max_wall_seconds: Option<f64>,
    retain_days: Option<f64>,
}

/// The directory of a server's own files (its SQLite store) unless `--data-dir` or `--store`
/// says otherwise: under the working directory, one entry to ignore in a repository.
pub const DEFAULT_DATA_DIR: &str = "signorini-data";

/// Per-job limits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Degrees of freedom.
    pub max_dofs: u64,
    /// Time steps (or analysis tasks).
    pub max_steps: u64,
    /// Estimated recorded output, bytes.
    pub max_output_bytes: u64,
    /// Estimated memory of a job (its compiled model and its run), bytes.
    pub max_memory_bytes: u64,
    /// Compiling a job's model.
    pub max_compile: std::time::Duration,
    /// A job's run, wall time (unlimited when `None`).
    pub max_wall: Option<std::time::Duration>,
}

/// A duration limit of `secs` seconds from `--FLAG`: positive and finite.
fn seconds(flag: &str, secs: f64) -> Result<std::time::Duration> {
    if secs.is_finite() && secs > 0.0 && secs <= 1e9 {
        Ok(std::time::Duration::from_secs_f64(secs))
    } else {
        bail!("--{flag} must be a positive number of seconds, not {secs}")
    }
}

impl Limits {
    /// The limits a server applies unless configured otherwise (and `signorini run` unless
    /// given `--no-limits`).
    pub const DEFAULT: Limits = Limits {
        max_dofs: 100_000,
        max_steps: 100_000_000,
        max_output_bytes: 1024 << 20,
        max_memory_bytes: 2048 << 20,
        max_compile: std::time::Duration::from_secs(30),
        max_wall: None,
    };
}

/// The PEM files of `--tls-cert` and `--tls-key`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TlsFiles {
    /// Certificate chain, leaf first.
    pub cert: PathBuf,
    /// Its private key.
    pub key: PathBuf,
}

/// The resolved configuration.
#[derive(Debug, Clone)]
pub struct ServeConfig {
    /// gRPC address.
    pub grpc_addr: SocketAddr,
    /// HTTP address.
    pub http_addr: SocketAddr,
    /// Store file, or PostgreSQL URL.
    pub store: PathBuf,
    /// A SQLite store's largest size, bytes (unlimited when `None`).
    pub store_max_bytes: Option<u64>,
    /// This replica's name (its claims in a PostgreSQL store).
    pub replica: String,
    /// A claim's lease in a PostgreSQL store.
    pub lease: std::time::Duration,
    /// zenoh listen endpoints.
    pub zenoh_listen: Vec<String>,
    /// zenoh connect endpoints.
    pub zenoh_connect: Vec<String>,
    /// zenoh configuration file.
    pub zenoh_config: Option<PathBuf>,
    /// Worker threads.
    pub workers: usize,
    /// Queue limit.
    pub queue_limit: usize,
    /// Bearer token for mutating calls.
    pub token: Option<String>,
    /// Per-client tokens with scopes (`--tokens`).
    pub tokens: Option<PathBuf>,
    /// TLS certificate and key (`--tls-cert`, `--tls-key`): both listeners speak TLS only.
    pub tls: Option<TlsFiles>,
    /// Per-job limits.
    pub limits: Limits,
    /// How long finished jobs are kept (forever when `None`).
    pub retain: Option<std::time::Duration>,
}

impl ServeConfig {
    /// Defaults < file < environment and flags (clap merges those two).
    pub fn resolve(args: ServeArgs) -> Result<ServeConfig> {
        let file = match &args.config {
            Some(p) => {
                let text = std::fs::read_to_string(p)
                    .with_context(|| format!("reading {}", p.display()))?;
                toml::from_str::<FileConfig>(&text)
                    .with_context(|| format!("parsing {}", p.display()))?
            }
            None => FileConfig::default(),
        };
        let cores = std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1);
        let pick = |flag: Vec<String>, file: Option<Vec<String>>, default: Vec<String>| {
            if !flag.is_empty() {
                flag
            } else {
                file.unwrap_or(default)
            }
        };
        let zenoh_config = args.zenoh_config.or(file.zenoh_config);
        let cfg = ServeConfig {
            grpc_addr: args
                .grpc_addr
                .or(file.grpc_addr)
                .unwrap_or(SocketAddr::from(([127, 0, 0, 1], 50051))),
            http_addr: args
                .http_addr
                .or(file.http_addr)
                .unwrap_or(SocketAddr::from(([127, 0, 0, 1], 8080))),
            store: args.store.or(file.store).unwrap_or_else(|| {
                args.data_dir
                    .or(file.data_dir)
                    .unwrap_or_else(|| PathBuf::from(DEFAULT_DATA_DIR))
                    .join("signorini.db")
            }),
            store_max_bytes: args
                .store_max_mb
                .or(file.store_max_mb)
                .map(|mb| mb.saturating_mul(1 << 20)),
            replica: match args.replica.or(file.replica) {
                Some(r) if !r.trim().is_empty() => r,
                _ => default_replica(),
            },
            lease: match args.lease_secs.or(file.lease_secs) {
                None => std::time::Duration::from_secs(10),
                Some(s) if s.is_finite() && (0.2..=3600.0).contains(&s) => {
                    std::time::Duration::from_secs_f64(s)
                }
                Some(s) => bail!("--lease-secs must be between 0.2 and 3600 seconds, not {s}"),
            },
            // A zenoh configuration file names its own endpoints.
            zenoh_listen: pick(
                args.zenoh_listen,
                file.zenoh_listen,
                if zenoh_config.is_some() {
                    Vec::new()
                } else {
                    vec!["tcp/127.0.0.1:7447".into()]
                },
            ),
            zenoh_connect: pick(args.zenoh_connect, file.zenoh_connect, Vec::new()),
            zenoh_config,
            workers: args.workers.or(file.workers).unwrap_or(cores),
            queue_limit: args.queue_limit.or(file.queue_limit).unwrap_or(256),
            token: args.token.or(file.token).filter(|t| !t.is_empty()),
            tokens: args.tokens.or(file.tokens),
            tls: match (
                args.tls_cert.or(file.tls_cert),
                args.tls_key.or(file.tls_key),
            ) {
                (Some(cert), Some(key)) => Some(TlsFiles { cert, key }),
                (None, None) => None,
                (Some(_), None) => bail!("--tls-cert needs --tls-key (its private key)"),
                (None, Some(_)) => bail!("--tls-key needs --tls-cert (its certificate)"),
            },
            limits: Limits {
                max_dofs: args
                    .max_dofs
                    .or(file.max_dofs)
                    .unwrap_or(Limits::DEFAULT.max_dofs),
                max_steps: args
                    .max_steps
                    .or(file.max_steps)
                    .unwrap_or(Limits::DEFAULT.max_steps),
                max_output_bytes: args
                    .max_output_mb
                    .or(file.max_output_mb)
                    .map_or(Limits::DEFAULT.max_output_bytes, |mb| {
                        mb.saturating_mul(1 << 20)
                    }),
                max_memory_bytes: args
                    .max_memory_mb
                    .or(file.max_memory_mb)
                    .unwrap_or(2048)
                    .saturating_mul(1 << 20),
                max_compile: seconds(
                    "max-compile-seconds",
                    args.max_compile_seconds
                        .or(file.max_compile_seconds)
                        .unwrap_or(30.0),
                )?,
                max_wall: args
                    .max_wall_seconds
                    .or(file.max_wall_seconds)
                    .map(|s| seconds("max-wall-seconds", s))
                    .transpose()?,
            },
            retain: None,
        };
        let cfg = match args.retain_days.or(file.retain_days) {
            None => cfg,
            Some(d) if d.is_finite() && d > 0.0 => ServeConfig {
                retain: Some(std::time::Duration::from_secs_f64(d * 86_400.0)),
                ..cfg
            },
            Some(d) => bail!("--retain-days must be a positive number of days, not {d}"),
        };
        if cfg.workers == 0 {
            bail!("workers must be at least 1");
        }
        if cfg.grpc_addr == cfg.http_addr && cfg.grpc_addr.port() != 0 {
            bail!(
                "--grpc-addr and --http-addr must differ ({})",
                cfg.grpc_addr
            );
        }
        Ok(cfg)
    }
}

/// A replica name unique among the replicas of one store: the host (`HOSTNAME`, a container's
/// or pod's name), the process id and a random part (two processes of one host, or two
/// containers whose main process are both pid 1, differ).
fn default_replica() -> String {
    let host = std::env::var("HOSTNAME")
        .ok()
        .filter(|h| !h.is_empty())
        .unwrap_or_else(|| "replica".into());
    // The last 8 hex digits of a job id are its random part.
    let id = crate::engine::ids::new_id();
    let random = &id[id.len().saturating_sub(8)..];
    format!("{host}-{}-{random}", std::process::id())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Issue 30: the default SQLite store lives in a data directory (`signorini-data/`, ignored
    /// by git), not as `signorini.db` in the working directory; `--data-dir` moves it and
    /// `--store` still names it outright.
    #[test]
    fn the_store_defaults_to_the_data_directory() {
        let cfg = ServeConfig::resolve(ServeArgs::default()).expect("defaults");
        assert_eq!(cfg.store, PathBuf::from("signorini-data/signorini.db"));
        let cfg = ServeConfig::resolve(ServeArgs {
            data_dir: Some(PathBuf::from("/srv/sim")),
            ..ServeArgs::default()
        })
        .expect("data dir");
        assert_eq!(cfg.store, PathBuf::from("/srv/sim/signorini.db"));
        let cfg = ServeConfig::resolve(ServeArgs {
            data_dir: Some(PathBuf::from("/srv/sim")),
            store: Some(PathBuf::from("jobs.db")),
            ..ServeArgs::default()
        })
        .expect("store");
        assert_eq!(cfg.store, PathBuf::from("jobs.db"));
    }
}
