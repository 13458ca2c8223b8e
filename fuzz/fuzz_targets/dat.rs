//! Siconos' `.dat` friction problem files (`signorini solve FILE`): the text read by the
//! service crate's own reader (`src/problem_file/`, compiled into this target from its source:
//! the service crate itself would bring zenoh and tonic into every instrumented build), then the
//! problem handed to the core (`RawProblem::to_fc3d`). A problem read and written again in each
//! storage (dense, sparse block, CSparse) must read back to the same W, q and μ
//! (`inputs/dat.rs`). `tests/fuzz_corpus.rs` replays the
//! corpus through the same calls.
#![no_main]

#[allow(dead_code)]
#[path = "../../src/problem_file/mod.rs"]
mod problem_file;

#[path = "../inputs/dat.rs"]
mod round_trip;

use libfuzzer_sys::fuzz_target;
use problem_file::dat;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let Ok(problem) = dat::parse(&text) else {
        return;
    };
    let _ = problem.to_fc3d();
    if let Err(e) = round_trip::round_trip(&problem) {
        panic!("{e}");
    }
});
