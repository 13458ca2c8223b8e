//! FCLib's HDF5 problem files (`signorini solve FILE.hdf5`): the datasets such a file holds,
//! decoded from the fuzzer's bytes (`inputs/fclib.rs`), checked and assembled by the service
//! crate's own code (`src/problem_file/fclib_layout.rs`, compiled into this target from its
//! source like the `dat` target's reader), then handed to the core. The HDF5 container itself is
//! the HDF5 library's (not instrumented, not linked here). `tests/fuzz_corpus.rs` replays the
//! corpus through the same calls, and through a real HDF5 file.
#![no_main]

#[allow(dead_code)]
#[path = "../../src/problem_file/mod.rs"]
mod problem_file;

#[path = "../inputs/fclib.rs"]
mod input;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Err(e) = input::check(&input::decode(data)) {
        panic!("{e}");
    }
});
