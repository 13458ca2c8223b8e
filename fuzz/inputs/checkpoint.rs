//! How an input of the `checkpoint` target becomes a checkpoint, shared by the target
//! (`fuzz_targets/checkpoint.rs`) and its corpus replay (`tests/fuzz_corpus.rs`), both of which
//! compile it from this file.
//!
//! Input: byte 0 picks the job ([`JOBS`]); then 4-byte edits of the payload (MessagePack) of
//! that job's real checkpoint of step [`AT`]: `[op, at_lo, at_hi, value]`, op % 3 = 0
//! overwrites the byte at `at`, 1 inserts `value` before it, 2 removes it (`at` modulo the
//! payload's length + 1). The edited payload is wrapped in a valid envelope (the job's spec
//! hash, the payload's length and FNV-1a checksum): otherwise every input would stop at the
//! checksum.

use signorini_core::checkpoint::{Checkpoint, FORMAT_VERSION};
use signorini_core::job::{self, Job};
use signorini_core::observer::{Columns, Observer, Progress, StepRecord};
use signorini_core::spec::JobSpec;
use std::ops::ControlFlow;

/// One example of each run kind: linear (Moreau–Jean, HHT, generalized-α, friction), nonlinear
/// Moreau–Jean, ns_generalized_alpha with joints, SOI2 (built-in and user model), WFEM.
pub const JOBS: [&str; 9] = [
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

/// Example `k` of [`JOBS`] (modulo their number) cut to [`STEPS`] steps, recording every step.
pub fn job(k: usize) -> Job {
    let mut spec: JobSpec = toml::from_str(JOBS[k % JOBS.len()]).expect("an example");
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
pub struct Keep(Option<Vec<u8>>);

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

/// The payload of `job`'s real checkpoint of step [`AT`] (the job is run to its end).
pub fn payload(job: &Job) -> Vec<u8> {
    let mut keep = Keep::default();
    job::run(job, 1, &mut keep).expect("the example runs");
    keep.0.expect("a checkpoint")[HEADER..].to_vec()
}

/// FNV-1a, 64 bits: the envelope's checksum.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// `payload` edited by `edits` (4 bytes each), wrapped in a valid envelope for `job`.
pub fn edited(job: &Job, payload: &[u8], edits: &[u8]) -> Vec<u8> {
    let mut payload = payload.to_vec();
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
    bytes.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    bytes.extend_from_slice(&job.spec_hash().to_le_bytes());
    bytes.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    bytes.extend_from_slice(&fnv1a(&payload).to_le_bytes());
    bytes.extend_from_slice(&payload);
    bytes
}
