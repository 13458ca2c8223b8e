//! The fuzz corpus (`fuzz/corpus/TARGET/`: the seeds, the inputs the coverage-guided fuzzer
//! kept, and every input that once failed) replayed through the calls its targets make
//! (`fuzz/fuzz_targets/`), so that CI keeps what a fuzzer found fixed without running one. Every
//! input must come back as an answer (a value, or a refusal naming its field or reason), never a
//! panic.

use signorini::problem_file::{RawProblem, dat};
use signorini::spec_file::{self, Format};
use signorini_core::checkpoint::{Checkpoint, FORMAT_VERSION};
use signorini_core::expr::{Expr, Param, Scope};
use signorini_core::job::{self, Job};
use signorini_core::observer::{Columns, Observer, Progress, StepRecord};
use signorini_core::spec::JobSpec;
use std::collections::BTreeMap;
use std::ops::ControlFlow;
use std::path::PathBuf;

/// The inputs of `fuzz/corpus/target`, with their names.
fn corpus(target: &str) -> Vec<(String, Vec<u8>)> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("fuzz/corpus")
        .join(target);
    let mut inputs: Vec<_> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|entry| {
            let path = entry.expect("corpus entry").path();
            let name = path
                .file_name()
                .expect("a file")
                .to_string_lossy()
                .into_owned();
            (name, std::fs::read(&path).expect("reading a corpus input"))
        })
        .collect();
    inputs.sort();
    assert!(!inputs.is_empty(), "no corpus in {}", dir.display());
    inputs
}

/// `spec_json.rs` and `spec_toml.rs`: every corpus input parses into a `JobSpec` or is refused,
/// and every parsed one is validated or refused naming a field; the seeds (the examples) hold
/// valid jobs.
#[test]
fn the_spec_corpus_is_answered() {
    type Parse = fn(&[u8]) -> Option<JobSpec>;
    let json: Parse = |d| serde_json::from_slice(d).ok();
    let toml: Parse = |d| {
        std::str::from_utf8(d)
            .ok()
            .and_then(|t| toml::from_str(t).ok())
    };
    for (target, parse) in [("spec_json", json), ("spec_toml", toml)] {
        let mut valid = 0;
        for (name, data) in corpus(target) {
            if let Some(spec) = parse(&data) {
                match Job::from_spec(&spec) {
                    Ok(_) => valid += 1,
                    Err(e) => assert!(!e.field.is_empty(), "{target}/{name}: {e}"),
                }
            }
        }
        assert!(valid >= 10, "{target}: only {valid} valid specs");
    }
}

/// `expr.rs`: every corpus text parses over `x, y, t` (with `k`, `c`) or is refused with a
/// reason; a parsed one, its derivative in `x` and its time derivative evaluate by tree and
/// tape.
#[test]
fn the_expression_corpus_is_answered() {
    let names = ["x".to_string(), "y".to_string(), "t".to_string()];
    let parameters = [
        ("k".to_string(), Param::Value(2.0)),
        ("c".to_string(), Param::Expr("k^2 + 1".into())),
    ];
    let scope = Scope::new(&names, &parameters).expect("the scope");
    let point = [0.75, -1.25, 2.5];
    let mut parsed = 0;
    for (name, data) in corpus("expr") {
        let Ok(text) = std::str::from_utf8(&data) else {
            continue;
        };
        match Expr::parse(text, &scope) {
            Ok(e) => {
                parsed += 1;
                for d in [Some(e.derivative(0)), e.time_derivative(1), Some(e)]
                    .into_iter()
                    .flatten()
                {
                    let _ = (d.eval(&point), d.compile().eval(&point));
                }
            }
            Err(err) => assert!(!err.to_string().is_empty(), "expr/{name}"),
        }
    }
    assert!(
        parsed >= 10,
        "only {parsed} expressions of the corpus parsed"
    );
}

/// `http_spec.rs`: every body is read (JSON, or TOML when its first byte is odd) by the
/// service's spec reader into a `JobSpec` and validated, or refused naming a field; the seeds
/// (the examples, in both spellings) hold valid jobs.
#[test]
fn the_http_body_corpus_is_answered() {
    let mut valid = 0;
    for (name, data) in corpus("http_spec") {
        let Some((&pick, body)) = data.split_first() else {
            continue;
        };
        let Ok(text) = std::str::from_utf8(body) else {
            continue;
        };
        let format = if pick % 2 == 1 {
            Format::Toml
        } else {
            Format::Json
        };
        match spec_file::parse(text, format) {
            Ok(spec) => match Job::from_spec(&spec) {
                Ok(_) => valid += 1,
                Err(e) => assert!(!e.field.is_empty(), "http_spec/{name}: {e}"),
            },
            Err(e) => assert!(!e.field.is_empty(), "http_spec/{name}: {e}"),
        }
    }
    assert!(valid >= 20, "only {valid} valid bodies");
}

/// W's non-zero entries, q and μ of a problem, as bits.
type ProblemBits = (BTreeMap<(usize, usize), u64>, Vec<u64>, Vec<u64>);

fn problem_bits(p: &RawProblem) -> ProblemBits {
    let w =
        p.w.entries()
            .filter(|&(_, _, x)| x != 0.0)
            .map(|(i, j, x)| ((i, j), x.to_bits()))
            .collect();
    let of = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect();
    (w, of(&p.q), of(&p.mu))
}

/// `dat.rs`: every text is read as a `.dat` problem or refused with a reason; a problem read
/// (of at most 48 rows) is written in each storage and reads back to the same bits. The seeds
/// (Siconos' problems of `tests/fixtures`, each storage) are read.
#[test]
fn the_problem_file_corpus_is_answered() {
    let mut read = 0;
    for (name, data) in corpus("dat") {
        let text = String::from_utf8_lossy(&data);
        let problem = match dat::parse(&text) {
            Ok(p) => p,
            Err(e) => {
                assert!(!e.to_string().is_empty(), "dat/{name}");
                continue;
            }
        };
        read += 1;
        let _ = problem.to_fc3d();
        if problem.w.size() > 48 {
            continue;
        }
        for storage in ["dense", "sparse_block", "csparse"] {
            let again = dat::parse(&dat::write(&problem, storage))
                .unwrap_or_else(|e| panic!("dat/{name} as {storage}: {e}"));
            assert_eq!(again.dimension, problem.dimension, "dat/{name}");
            assert!(
                problem_bits(&again) == problem_bits(&problem),
                "dat/{name} as {storage}: another problem read back"
            );
        }
    }
    assert!(read >= 3, "only {read} problems of the corpus read");
}

/// The jobs of `checkpoint.rs`, one of each run kind (the same list, in the same order).
const CHECKPOINT_JOBS: [&str; 9] = [
    "bouncing_ball",
    "chain_ns_hht",
    "bar_ns_generalized_alpha",
    "chain_rough_wall",
    "double_pendulum_rough_wall",
    "slider_crank_clearance_joints",
    "jay_negrut_test",
    "pendulum_lagrangian",
    "wfem_dep_bar",
];

/// Keeps the encoded checkpoint of step 10.
#[derive(Default)]
struct KeepCheckpoint(Option<Vec<u8>>);

impl Observer for KeepCheckpoint {
    fn start(&mut self, _: &Columns) {}
    fn observe(&mut self, _: &StepRecord<'_>) -> ControlFlow<()> {
        ControlFlow::Continue(())
    }
    fn checkpoint_due(&mut self, p: Progress) -> bool {
        p.done == 10
    }
    fn checkpoint(&mut self, c: &mut Checkpoint) {
        self.0 = c.encode().ok();
    }
}

/// `checkpoint.rs`: byte 0 picks a job (an example cut to 30 steps), the rest edits the payload
/// of its real checkpoint of step 10 (4-byte edits: overwrite, insert, remove), which is wrapped
/// in a valid envelope, read and resumed: every input is refused with a reason or runs to the
/// job's end, never a panic. The seeds (one unedited checkpoint per job) all resume.
#[test]
fn the_checkpoint_corpus_is_answered() {
    const HEADER: usize = 8 + 4 + 8 + 8 + 8;
    let fnv1a = |bytes: &[u8]| {
        bytes.iter().fold(0xcbf2_9ce4_8422_2325_u64, |h, &b| {
            (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
        })
    };
    let jobs: Vec<(Job, Vec<u8>)> = CHECKPOINT_JOBS
        .iter()
        .map(|name| {
            let path = format!("{}/examples/{name}.toml", env!("CARGO_MANIFEST_DIR"));
            let text = std::fs::read_to_string(&path).expect("an example");
            let mut spec: JobSpec = toml::from_str(&text).expect("a spec");
            let time = spec.time.as_mut().expect("a time section");
            match time.steps {
                Some(n) => time.steps = Some(n.min(30)),
                None => time.t_end = Some(time.t_end.expect("t_end").min(30.0 * time.h)),
            }
            spec.output.every = 1;
            let job = Job::from_spec(&spec).expect("a valid example");
            let mut keep = KeepCheckpoint::default();
            job::run(&job, 1, &mut keep).expect("the example runs");
            let payload = keep.0.expect("a checkpoint")[HEADER..].to_vec();
            (job, payload)
        })
        .collect();
    let mut resumed = 0;
    for (name, data) in corpus("checkpoint") {
        let Some((&pick, edits)) = data.split_first() else {
            continue;
        };
        let (job, payload) = &jobs[usize::from(pick) % jobs.len()];
        let mut payload = payload.clone();
        for e in edits.chunks_exact(4) {
            let at = usize::from(u16::from_le_bytes([e[1], e[2]])) % (payload.len() + 1);
            match (e[0] % 3, at < payload.len()) {
                (0, true) => payload[at] = e[3],
                (1, _) => payload.insert(at, e[3]),
                (2, true) => {
                    payload.remove(at);
                }
                _ => {}
            }
        }
        let mut bytes = b"SIGNCKPT".to_vec();
        bytes.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        bytes.extend_from_slice(&job.spec_hash().to_le_bytes());
        bytes.extend_from_slice(&(payload.len() as u64).to_le_bytes());
        bytes.extend_from_slice(&fnv1a(&payload).to_le_bytes());
        bytes.extend_from_slice(&payload);
        match job.read_checkpoint(&bytes) {
            Ok(checkpoint) => {
                if job::resume(job, 1, &mut KeepCheckpoint::default(), &checkpoint).is_ok() {
                    resumed += 1;
                }
            }
            Err(e) => assert!(!e.to_string().is_empty(), "checkpoint/{name}"),
        }
    }
    assert!(
        resumed >= CHECKPOINT_JOBS.len(),
        "only {resumed} checkpoints of the corpus resumed"
    );
}
