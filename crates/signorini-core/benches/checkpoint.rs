//! Cost of checkpoints: the overhead on steps/s of the bar (N = 1000, Moreau–Jean θ = ½) at the
//! default period (a clock read every 16th step, one checkpoint per 30 s) and, as a worst case,
//! with a checkpoint every 1000 steps; and the size, encode, write (+ fsync) and decode times of
//! one checkpoint for N = 10³, 10⁴, 10⁵.
//!
//! ```text
//! cargo bench -p signorini-core --bench checkpoint
//! ```
//!
//! Prints one JSON line per measurement.

// Only the core library must stay pure (clippy.toml): a benchmark times itself, writes a file
// and prints.
#![allow(
    clippy::disallowed_macros,
    clippy::disallowed_methods,
    clippy::disallowed_types
)]

use signorini_core::checkpoint::Checkpoint;
use signorini_core::job::{self, Job};
use signorini_core::observer::{Observer, Progress, StepRecord};
use signorini_core::spec::JobSpec;
use std::io::Write;
use std::ops::ControlFlow;
use std::time::{Duration, Instant};

/// How the observer checkpoints.
#[derive(Clone, Copy)]
enum Period {
    /// Never asked.
    Off,
    /// As `signorini run`: the clock read every 16th step, a checkpoint after `0` of wall time.
    Seconds(Duration),
    /// Every `0` steps.
    Steps(u64),
}

/// Counts records; checkpoints per `period`, encoding each one (as a caller would before
/// writing it), and keeps the last one's bytes.
struct Bench {
    period: Period,
    last: Instant,
    records: u64,
    checkpoints: u64,
    bytes: Vec<u8>,
}

impl Observer for Bench {
    fn observe(&mut self, _: &StepRecord<'_>) -> ControlFlow<()> {
        self.records += 1;
        ControlFlow::Continue(())
    }

    fn checkpoint_due(&mut self, p: Progress) -> bool {
        match self.period {
            Period::Off => false,
            Period::Seconds(s) => p.done.is_multiple_of(16) && self.last.elapsed() >= s,
            Period::Steps(n) => p.done.is_multiple_of(n),
        }
    }

    fn checkpoint(&mut self, checkpoint: &mut Checkpoint) {
        self.bytes = checkpoint.encode().expect("encodes");
        self.checkpoints += 1;
        self.last = Instant::now();
    }
}

fn bar(elements: usize, steps: u64) -> Job {
    let spec: JobSpec = toml::from_str(&format!(
        r#"
        [model]
        scene = "bar"
        elements = {elements}
        gap = 0.001
        initial_velocity = 1.0
        [integrator]
        scheme = "moreau_jean"
        [time]
        h = 1e-4
        steps = {steps}
        [output]
        every = 100
        "#
    ))
    .expect("spec");
    Job::from_spec(&spec).expect("valid")
}

/// Best of three: wall seconds of the run, checkpoints taken, the last one's bytes.
fn timed(job: &Job, period: Period) -> (f64, u64, Vec<u8>) {
    let mut best = (f64::INFINITY, 0, Vec::new());
    for _ in 0..3 {
        let mut b = Bench {
            period,
            last: Instant::now(),
            records: 0,
            checkpoints: 0,
            bytes: Vec::new(),
        };
        let t0 = Instant::now();
        job::run(job, 1, &mut b).expect("run");
        let wall = t0.elapsed().as_secs_f64();
        if wall < best.0 {
            best = (wall, b.checkpoints, b.bytes);
        }
    }
    best
}

fn main() {
    let quick = std::env::args().any(|a| a == "--quick");
    // The bar N = 1000: steps/s without checkpoints, at the default period, and every 1000 steps.
    let steps = if quick { 20_000 } else { 200_000 };
    let job = bar(1000, steps);
    let (off, _, _) = timed(&job, Period::Off);
    let (default, n_default, _) = timed(&job, Period::Seconds(Duration::from_secs(30)));
    let (dense, n_dense, bytes) = timed(&job, Period::Steps(1000));
    let per_checkpoint = (dense - off) / n_dense as f64;
    // At the default period a run pays the clock reads, and one checkpoint per 30 s.
    let overhead_default = (default - off) / off + per_checkpoint / 30.0;
    println!(
        "{{\"bench\":\"checkpoint_overhead\",\"elements\":1000,\"steps\":{steps},\"steps_per_s_off\":{:.0},\"steps_per_s_default_period\":{:.0},\"checkpoints_default_period\":{n_default},\"steps_per_s_every_1000_steps\":{:.0},\"checkpoints_every_1000_steps\":{n_dense},\"checkpoint_s\":{per_checkpoint:.3e},\"checkpoint_bytes\":{},\"overhead_default_period\":{overhead_default:.4}}}",
        steps as f64 / off,
        steps as f64 / default,
        steps as f64 / dense,
        bytes.len()
    );

    // One checkpoint of larger bars: size, encode, write + fsync, decode.
    let dir =
        std::env::temp_dir().join(format!("signorini-checkpoint-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    for elements in [1_000usize, 10_000, 100_000] {
        let job = bar(elements, 40);
        let mut b = Bench {
            period: Period::Steps(20),
            last: Instant::now(),
            records: 0,
            checkpoints: 0,
            bytes: Vec::new(),
        };
        job::run(&job, 1, &mut b).expect("run");
        // Encode again, timed (the run's own encode is inside its loop).
        let checkpoint = job.read_checkpoint(&b.bytes).expect("decodes");
        let t0 = Instant::now();
        let bytes = checkpoint.encode().expect("encodes");
        let encode = t0.elapsed().as_secs_f64();
        let path = dir.join("checkpoint.bin");
        let t0 = Instant::now();
        let mut f = std::fs::File::create(&path).expect("create");
        f.write_all(&bytes).expect("write");
        f.sync_data().expect("sync");
        drop(f);
        let write = t0.elapsed().as_secs_f64();
        let t0 = Instant::now();
        let back = job.read_checkpoint(&bytes).expect("decodes");
        let decode = t0.elapsed().as_secs_f64();
        assert_eq!(back.step(), checkpoint.step());
        println!(
            "{{\"bench\":\"checkpoint_size\",\"elements\":{elements},\"bytes\":{},\"bytes_per_dof\":{:.1},\"encode_s\":{encode:.3e},\"write_fsync_s\":{write:.3e},\"decode_s\":{decode:.3e}}}",
            bytes.len(),
            bytes.len() as f64 / elements as f64
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
