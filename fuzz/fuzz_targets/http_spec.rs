//! The body of `POST /v1/jobs` as the HTTP route reads it: the text through the service
//! crate's spec reader (`src/spec_file.rs`, compiled into this target from its source: the
//! service crate itself would bring zenoh and tonic into every instrumented build), JSON or, for
//! `content-type: application/toml`, TOML (byte 0 picks: odd for TOML); its errors name the field
//! by its path, refined per scene and scheme; then `Job::from_spec`. `tests/fuzz_corpus.rs`
//! replays the corpus through the same calls.
#![no_main]

#[allow(dead_code)]
#[path = "../../src/spec_file.rs"]
mod spec_file;

use libfuzzer_sys::fuzz_target;
use signorini_core::job::Job;
use spec_file::Format;

fuzz_target!(|data: &[u8]| {
    let Some((&pick, body)) = data.split_first() else {
        return;
    };
    let Ok(text) = std::str::from_utf8(body) else {
        return;
    };
    let format = if pick % 2 == 1 {
        Format::Toml
    } else {
        Format::Json
    };
    match spec_file::parse(text, format) {
        Ok(spec) => {
            if let Err(e) = Job::from_spec(&spec) {
                assert!(!e.field.is_empty(), "{e}");
            }
        }
        Err(e) => assert!(!e.field.is_empty(), "{e}"),
    }
});
