//! A job spec as a TOML file (`signorini run`, `submit`, `check`, and HTTP with
//! `content-type: application/toml`): TOML into `JobSpec`, then validated (`Job::from_spec`).
#![no_main]

use libfuzzer_sys::fuzz_target;
use signorini_core::job::Job;
use signorini_core::spec::JobSpec;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data)
        && let Ok(spec) = toml::from_str::<JobSpec>(text)
    {
        let _ = Job::from_spec(&spec);
    }
});
