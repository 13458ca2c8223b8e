//! The fuzz corpus (`fuzz/corpus/TARGET/`: the seeds, the inputs the coverage-guided fuzzer
//! kept, and every input that once failed) replayed through the calls its targets make
//! (`fuzz/fuzz_targets/`), so that CI keeps what a fuzzer found fixed without running one. Every
//! input must come back as an answer (a value, or a refusal naming its field or reason), never a
//! panic.

#[path = "../fuzz/inputs/checkpoint.rs"]
mod checkpoint_input;
#[path = "../fuzz/inputs/dat.rs"]
mod dat_round_trip;
// Its `encode` is used only by the test of the seeds, which needs an HDF5 library.
#[cfg_attr(not(feature = "hdf5"), allow(dead_code))]
#[path = "../fuzz/inputs/fclib.rs"]
mod fclib_input;

use signorini::problem_file::{self, dat};
use signorini::spec_file::{self, Format};
use signorini_core::expr::{Expr, Param, Scope};
use signorini_core::job::{self, Job};
use signorini_core::spec::JobSpec;
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
        if let Err(e) = dat_round_trip::round_trip(&problem) {
            panic!("dat/{name}: {e}");
        }
    }
    assert!(read >= 3, "only {read} problems of the corpus read");
}

/// `checkpoint.rs`: byte 0 picks a job (an example cut to 30 steps), the rest edits the payload
/// of its real checkpoint of step 10 (4-byte edits: overwrite, insert, remove), which is wrapped
/// in a valid envelope, read and resumed: every input is refused with a reason or runs to the
/// job's end, never a panic. The seeds (one unedited checkpoint per job) all resume.
#[test]
fn the_checkpoint_corpus_is_answered() {
    let jobs: Vec<(Job, Vec<u8>)> = (0..checkpoint_input::JOBS.len())
        .map(|k| {
            let job = checkpoint_input::job(k);
            let payload = checkpoint_input::payload(&job);
            (job, payload)
        })
        .collect();
    let mut resumed = 0;
    for (name, data) in corpus("checkpoint") {
        let Some((&pick, edits)) = data.split_first() else {
            continue;
        };
        let (job, payload) = &jobs[usize::from(pick) % jobs.len()];
        let bytes = checkpoint_input::edited(job, payload, edits);
        match job.read_checkpoint(&bytes) {
            Ok(checkpoint) => {
                if job::resume(job, 1, &mut checkpoint_input::Keep::default(), &checkpoint).is_ok()
                {
                    resumed += 1;
                }
            }
            Err(e) => assert!(!e.to_string().is_empty(), "checkpoint/{name}"),
        }
    }
    assert!(
        resumed >= checkpoint_input::JOBS.len(),
        "only {resumed} checkpoints of the corpus resumed"
    );
}

/// `fclib.rs`: the datasets every input decodes to are read into a problem or refused with a
/// reason, and a problem read stores again (W as CSR) to the same bits. With HDF5 built in, each
/// input is also written to a real FCLib file, which reads back to the same datasets and the
/// same answer. The seeds (FCLib files of `tests/fixtures`, and Siconos' `.dat` problems stored
/// as FCLib stores them) are read.
#[test]
fn the_fclib_corpus_is_answered() {
    let mut read = 0;
    #[cfg(feature = "hdf5")]
    let (dir, mut through_hdf5) = (tempfile::tempdir().expect("a temporary directory"), 0);
    for (name, data) in corpus("fclib") {
        let datasets = fclib_input::decode(&data);
        if let Err(e) = fclib_input::check(&datasets) {
            panic!("fclib/{name}: {e}");
        }
        let answer = datasets.assemble().map_err(|e| e.to_string());
        read += usize::from(answer.is_ok());
        #[cfg(feature = "hdf5")]
        {
            use signorini::problem_file::fclib;
            let path = dir.path().join(&name);
            // Integers beyond FCLib's 32-bit int cannot be stored (refused, naming them).
            if fclib::write_datasets(&path, &datasets).is_ok() {
                through_hdf5 += 1;
                let back = fclib::read_datasets(&path).expect("a file just written");
                assert_eq!(format!("{back:?}"), format!("{datasets:?}"), "fclib/{name}");
                let again = fclib::read(&path).map_err(|e| e.to_string());
                assert_eq!(format!("{again:?}"), format!("{answer:?}"), "fclib/{name}");
            }
        }
    }
    assert!(read >= 5, "only {read} problems of the corpus read");
    #[cfg(feature = "hdf5")]
    assert!(
        through_hdf5 >= 5,
        "only {through_hdf5} inputs went through HDF5"
    );
}

/// The `fclib` corpus' seeds are the fixtures encoded (`fuzz/inputs/fclib.rs`): FCLib's two
/// files, two `.dat` problems stored as FCLib stores them (3D and 2D), and a small global problem.
/// `SIGNORINI_WRITE_FUZZ_SEEDS=1` writes them instead of comparing.
#[cfg(feature = "hdf5")]
#[test]
fn the_fclib_seeds_are_the_fixtures_encoded() {
    use signorini::problem_file::{fclib, fclib_layout::Datasets};
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let fixture = |name: &str| root.join("tests/fixtures/friction").join(name);
    let mut seeds = Vec::new();
    for name in [
        "Box_Stacks-i0122-82-5.hdf5",
        "LMGC_100_PR_PerioBox-i00361-60-03000.hdf5",
    ] {
        let datasets = fclib::read_datasets(&fixture(name)).expect("a fixture");
        seeds.push((name.to_string(), datasets));
    }
    for name in ["Rover1039.dat", "FrictionContactProblem00031.dat"] {
        let problem = problem_file::read(&fixture(name)).expect("a fixture");
        seeds.push((name.to_string(), Datasets::local(&problem)));
    }
    let h = [(0, 0, 1.0), (1, 0, 0.5), (0, 1, -1.0), (1, 2, 2.0)];
    let global = Datasets::global(3, &[2.0, 4.0], &h, &[1.0, -8.0], &[0.1, 0.2, 0.3], &[0.6]);
    seeds.push(("global-2-dofs".to_string(), global));
    let write = std::env::var_os("SIGNORINI_WRITE_FUZZ_SEEDS").is_some();
    for (name, datasets) in seeds {
        let bytes = fclib_input::encode(&datasets).expect("arrays of at most 65 535 entries");
        assert_eq!(
            format!("{:?}", fclib_input::decode(&bytes)),
            format!("{datasets:?}"),
            "{name}: encoded and decoded"
        );
        let path = root.join("fuzz/corpus/fclib").join(format!("seed-{name}"));
        if write {
            std::fs::create_dir_all(path.parent().expect("the corpus")).expect("the corpus");
            std::fs::write(&path, &bytes).expect("writing a seed");
        } else {
            let kept = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            assert!(kept == bytes, "{}: not the fixture encoded", path.display());
        }
    }
}
