//! Siconos' `.dat` friction problem files (`signorini solve FILE`): the text read by the
//! service crate's own reader (`src/problem_file/`, compiled into this target from its source:
//! the service crate itself would bring zenoh and tonic into every instrumented build), then the
//! problem handed to the core (`RawProblem::to_fc3d`). A problem read and written again in each
//! storage (dense, sparse block, CSparse) must read back to the same W, q and μ: the writer
//! prints every number so that it parses to the same bits. `tests/fuzz_corpus.rs` replays the
//! corpus through the same calls.
#![no_main]

#[allow(dead_code)]
#[path = "../../src/problem_file/mod.rs"]
mod problem_file;

use libfuzzer_sys::fuzz_target;
use problem_file::{RawProblem, dat};
use std::collections::BTreeMap;

/// Largest problem (rows of W) written back: a dense W of `size²` numbers.
const ROUND_TRIP_SIZE: usize = 48;

/// W's non-zero entries, q and μ, as bits.
type Bits = (BTreeMap<(usize, usize), u64>, Vec<u64>, Vec<u64>);

fn bits(p: &RawProblem) -> Bits {
    let w =
        p.w.entries()
            .filter(|&(_, _, x)| x != 0.0)
            .map(|(i, j, x)| ((i, j), x.to_bits()))
            .collect();
    let of = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect();
    (w, of(&p.q), of(&p.mu))
}

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let Ok(problem) = dat::parse(&text) else {
        return;
    };
    let _ = problem.to_fc3d();
    if problem.w.size() > ROUND_TRIP_SIZE {
        return;
    }
    let want = bits(&problem);
    for storage in ["dense", "sparse_block", "csparse"] {
        let again = dat::parse(&dat::write(&problem, storage))
            .unwrap_or_else(|e| panic!("written as {storage}, read back: {e}"));
        assert_eq!(again.dimension, problem.dimension, "{storage}");
        assert!(bits(&again) == want, "{storage}: another problem read back");
    }
});
