//! The checkpoint decoder and resume (`run --resume DIR` reads `DIR/checkpoint.bin`; a
//! restarted server reads its store's): a real checkpoint of a small job of each run kind,
//! edited by the input, wrapped in a valid envelope (the job's spec hash, the payload's length
//! and FNV-1a checksum: otherwise every input would stop at the checksum), then
//! `Job::read_checkpoint` and `job::resume` to the job's end. `tests/fuzz_corpus.rs` replays
//! the corpus through the same calls.
//!
//! Input: byte 0 picks the job ([`JOBS`]); then 4-byte edits of the checkpoint's payload
//! (MessagePack): `[op, at_lo, at_hi, value]`, op % 3 = 0 overwrites the byte at `at`, 1
//! inserts `value` before it, 2 removes it (`at` modulo the payload's length + 1).
#![no_main]

use libfuzzer_sys::fuzz_target;
use signorini_core::checkpoint::Checkpoint;
use signorini_core::job::{self, Job};
use signorini_core::observer::{Columns, Observer, Progress, StepRecord};
use signorini_core::spec::JobSpec;
use std::collections::HashMap;
use std::ops::ControlFlow;
use std::sync::{LazyLock, Mutex};

/// One example of each run kind: linear (Moreau–Jean, HHT, generalized-α, friction), nonlinear
/// Moreau–Jean, ns_generalized_alpha with joints, SOI2 (built-in and user model), WFEM.
const JOBS: [&str; 9] = [
    include_str!("../../examples/bouncing_ball.toml"),
    include_str!("../../examples/chain_ns_hht.toml"),
    include_str!("../../examples/bar_ns_generalized_alpha.toml"),
    include_str!("../../examples/chain_rough_wall.toml"),
    include_str!("../../examples/double_pendulum_rough_wall.toml"),
    include_str!("../../examples/slider_crank_clearance_joints.toml"),
    include_str!("../../examples/jay_negrut_test.toml"),
    include_str!("../../examples/pendulum_lagrangian.toml"),
    include_str!("../../examples/wfem_dep_bar.toml"),
];

/// Steps of each job, and the step of its checkpoint.
const STEPS: u64 = 30;
const AT: u64 = 10;
/// Bytes before a checkpoint's payload: magic, format version, spec hash, length, checksum.
const HEADER: usize = 8 + 4 + 8 + 8 + 8;

/// Example `k` cut to [`STEPS`] steps, recording every step.
fn job(k: usize) -> Job {
    let mut spec: JobSpec = toml::from_str(JOBS[k]).expect("an example");
    let time = spec.time.as_mut().expect("a time section");
    match time.steps {
        Some(n) => time.steps = Some(n.min(STEPS)),
        None => time.t_end = Some(time.t_end.expect("t_end").min(STEPS as f64 * time.h)),
    }
    spec.output.every = 1;
    Job::from_spec(&spec).expect("a valid example")
}

/// Keeps the checkpoint of step [`AT`].
#[derive(Default)]
struct Keep(Option<Vec<u8>>);

impl Observer for Keep {
    fn start(&mut self, _: &Columns) {}
    fn observe(&mut self, _: &StepRecord<'_>) -> ControlFlow<()> {
        ControlFlow::Continue(())
    }
    fn checkpoint_due(&mut self, p: Progress) -> bool {
        p.done == AT
    }
    fn checkpoint(&mut self, c: &mut Checkpoint) {
        self.0 = c.encode().ok();
    }
}

/// The payload of the real checkpoint of job `k` (computed once).
fn payload(k: usize, job: &Job) -> Vec<u8> {
    static CACHE: LazyLock<Mutex<HashMap<usize, Vec<u8>>>> = LazyLock::new(Default::default);
    let mut cache = CACHE.lock().unwrap_or_else(|p| p.into_inner());
    cache
        .entry(k)
        .or_insert_with(|| {
            let mut keep = Keep::default();
            job::run(job, 1, &mut keep).expect("the example runs");
            keep.0.expect("a checkpoint")[HEADER..].to_vec()
        })
        .clone()
}

/// FNV-1a, 64 bits: the envelope's checksum.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

fuzz_target!(|data: &[u8]| {
    let Some((&pick, edits)) = data.split_first() else {
        return;
    };
    let k = usize::from(pick) % JOBS.len();
    let job = job(k);
    let mut payload = payload(k, &job);
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
    bytes.extend_from_slice(&signorini_core::checkpoint::FORMAT_VERSION.to_le_bytes());
    bytes.extend_from_slice(&job.spec_hash().to_le_bytes());
    bytes.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    bytes.extend_from_slice(&fnv1a(&payload).to_le_bytes());
    bytes.extend_from_slice(&payload);
    if let Ok(checkpoint) = job.read_checkpoint(&bytes) {
        let _ = job::resume(&job, 1, &mut Keep::default(), &checkpoint);
    }
});
