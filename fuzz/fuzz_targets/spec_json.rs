//! A job spec as the HTTP body of `POST /v1/jobs` and the `json` field of gRPC `SubmitJob`
//! carry it: JSON into `JobSpec`, then validated (`Job::from_spec`).
#![no_main]

use libfuzzer_sys::fuzz_target;
use signorini_core::job::Job;
use signorini_core::spec::JobSpec;

fuzz_target!(|data: &[u8]| {
    if let Ok(spec) = serde_json::from_slice::<JobSpec>(data) {
        let _ = Job::from_spec(&spec);
    }
});
