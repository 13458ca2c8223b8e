//! The fuzz corpus (`fuzz/corpus/TARGET/`: the seeds, the inputs the coverage-guided fuzzer
//! kept, and every input that once failed) replayed through the calls its targets make
//! (`fuzz/fuzz_targets/`), so that CI keeps what a fuzzer found fixed without running one. Every
//! input must come back as an answer (a value, or a refusal naming its field or reason), never a
//! panic.

use signorini_core::expr::{Expr, Param, Scope};
use signorini_core::job::Job;
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
