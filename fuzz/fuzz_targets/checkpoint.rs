//! The checkpoint decoder and resume (`run --resume DIR` reads `DIR/checkpoint.bin`; a
//! restarted server reads its store's): a real checkpoint of a small job of each run kind,
//! edited by the input and wrapped in a valid envelope (`inputs/checkpoint.rs` says how), then
//! `Job::read_checkpoint` and `job::resume` to the job's end. `tests/fuzz_corpus.rs` replays
//! the corpus through the same calls.
#![no_main]

#[path = "../inputs/checkpoint.rs"]
mod input;

use libfuzzer_sys::fuzz_target;
use signorini_core::job;
use std::collections::HashMap;
use std::sync::{LazyLock, Mutex};

/// The payload of the real checkpoint of job `k` (computed once).
fn payload(k: usize) -> Vec<u8> {
    static CACHE: LazyLock<Mutex<HashMap<usize, Vec<u8>>>> = LazyLock::new(Default::default);
    let mut cache = CACHE.lock().unwrap_or_else(|p| p.into_inner());
    cache
        .entry(k)
        .or_insert_with(|| input::payload(&input::job(k)))
        .clone()
}

fuzz_target!(|data: &[u8]| {
    let Some((&pick, edits)) = data.split_first() else {
        return;
    };
    let k = usize::from(pick) % input::JOBS.len();
    let job = input::job(k);
    let bytes = input::edited(&job, &payload(k), edits);
    if let Ok(checkpoint) = job.read_checkpoint(&bytes) {
        let _ = job::resume(&job, 1, &mut input::Keep::default(), &checkpoint);
    }
});
