//! Checkpoints and resume: for every scheme family, a run interrupted after a checkpoint and
//! resumed from that checkpoint's bytes in a fresh job gives the uninterrupted run bit for bit:
//! every recorded value of every column (the energy ledger included), the steps and times of the
//! records, the summary and the chart data. Foreign, damaged or mismatched checkpoints are
//! refused with their reason.

// The test reads the examples from disk; the core library itself does no I/O.
#![allow(clippy::disallowed_methods)]

use signorini_core::checkpoint::{Checkpoint, CheckpointError, FORMAT_VERSION, RunKind};
use signorini_core::job::{self, Job};
use signorini_core::observer::{Columns, Observer, Progress, Recorder, StepRecord};
use signorini_core::outcome::{RunError, RunOutput};
use signorini_core::spec::JobSpec;
use std::ops::ControlFlow;

/// An example spec cut to at most `steps` steps, recording every `every`-th.
fn example(name: &str, steps: u64, every: u64) -> JobSpec {
    let path = format!("{}/../../examples/{name}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap();
    let mut spec: JobSpec = toml::from_str(&text).unwrap();
    let time = spec.time.as_mut().unwrap();
    match time.steps {
        Some(n) => time.steps = Some(n.min(steps)),
        None => time.t_end = Some(time.t_end.unwrap().min(steps as f64 * time.h)),
    }
    spec.output.every = every;
    spec
}

/// Records everything, asks for a checkpoint every `period` steps, keeps the last one's bytes,
/// and stops the run (as a kill would) after `stop` steps.
struct Interrupted {
    rec: Recorder,
    period: u64,
    stop: u64,
    last: Option<(u64, Vec<u8>)>,
}

impl Observer for Interrupted {
    fn start(&mut self, columns: &Columns) {
        self.rec.start(columns);
    }
    fn observe(&mut self, record: &StepRecord<'_>) -> ControlFlow<()> {
        self.rec.observe(record)
    }
    fn progress(&mut self, p: Progress) -> ControlFlow<()> {
        if p.done >= self.stop {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    }
    fn checkpoint_due(&mut self, p: Progress) -> bool {
        p.done.is_multiple_of(self.period)
    }
    fn checkpoint(&mut self, c: &mut Checkpoint) {
        self.last = Some((c.step(), c.encode().unwrap()));
    }
}

fn bits(rows: &[Vec<f64>]) -> Vec<Vec<u64>> {
    rows.iter()
        .map(|r| r.iter().map(|x| x.to_bits()).collect())
        .collect()
}

/// The output without its wall time, as text that tells every f64 apart.
fn printed(out: &RunOutput) -> (String, String, String) {
    (
        serde_json::to_string(&out.summary).unwrap(),
        format!("{:?}", out.tables),
        format!("{:?}", out.charts),
    )
}

/// Runs `spec` whole; then runs it again, interrupted after `stop` steps with a checkpoint every
/// `period`, and resumes a fresh job from the last checkpoint's bytes; both must agree bit for
/// bit. Returns the step of the checkpoint resumed from.
fn resumes_bit_for_bit(spec: &JobSpec, period: u64, stop: u64) -> u64 {
    let job = Job::from_spec(spec).unwrap();
    let mut whole = Recorder::default();
    let full = job::run(&job, 1, &mut whole).unwrap();

    let mut cut = Interrupted {
        rec: Recorder::default(),
        period,
        stop,
        last: None,
    };
    let stopped = job::run(&job, 1, &mut cut);
    assert!(
        matches!(stopped, Err(RunError::Stopped { .. })),
        "{stopped:?}"
    );
    let (step, bytes) = cut.last.expect("a checkpoint before the stop");

    let fresh = Job::from_spec(spec).unwrap();
    let checkpoint = fresh.read_checkpoint(&bytes).unwrap();
    assert_eq!(checkpoint.step(), step);
    let kept = checkpoint.records() as usize;
    assert!(kept > 1 && kept <= cut.rec.rows.len());
    let mut rest = Recorder::default();
    let resumed = job::resume(&fresh, 1, &mut rest, &checkpoint).unwrap();

    assert_eq!(rest.columns, whole.columns);
    assert!(!rest.rows.is_empty());
    let mut rows = cut.rec.rows[..kept].to_vec();
    rows.extend(rest.rows.iter().cloned());
    let mut steps = cut.rec.steps[..kept].to_vec();
    steps.extend(&rest.steps);
    let mut t = cut.rec.t[..kept].to_vec();
    t.extend(&rest.t);
    assert_eq!(steps, whole.steps);
    assert_eq!(
        t.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
        whole.t.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
    );
    assert_eq!(rows.len(), whole.rows.len());
    for (i, (a, b)) in bits(&rows).iter().zip(bits(&whole.rows)).enumerate() {
        assert_eq!(*a, b, "record {i} (step {}) differs", whole.steps[i]);
    }
    assert_eq!(printed(&resumed), printed(&full));
    step
}

#[test]
fn moreau_jean_bar_resumes_bit_for_bit() {
    let spec = example("bar.toml", 600, 7);
    assert_eq!(resumes_bit_for_bit(&spec, 100, 350), 300);
}

#[test]
fn moreau_jean_with_friction_resumes_bit_for_bit() {
    let spec = example("chain_rough_wall.toml", 500, 3);
    resumes_bit_for_bit(&spec, 61, 400);
}

#[test]
fn moreau_jean_variant_resumes_bit_for_bit() {
    let spec = example("linear.toml", 400, 1);
    resumes_bit_for_bit(&spec, 50, 222);
}

#[test]
fn alpha_family_resumes_bit_for_bit() {
    // The generalized-α on the bar (filters and accelerations), ns_hht on the chain.
    resumes_bit_for_bit(&example("bar_ns_generalized_alpha.toml", 600, 5), 97, 450);
    resumes_bit_for_bit(&example("chain_ns_hht.toml", 500, 4), 53, 300);
}

#[test]
fn position_contact_resumes_bit_for_bit() {
    resumes_bit_for_bit(
        &example("bar_newmark_position_contact.toml", 600, 3),
        111,
        500,
    );
}

#[test]
fn nonlinear_moreau_jean_resumes_bit_for_bit() {
    resumes_bit_for_bit(&example("rocking_block.toml", 400, 3), 41, 300);
    resumes_bit_for_bit(&example("rocking_block_friction.toml", 400, 2), 37, 250);
}

#[test]
fn ns_generalized_alpha_resumes_bit_for_bit() {
    resumes_bit_for_bit(
        &example("rocking_block_ns_generalized_alpha.toml", 300, 3),
        29,
        200,
    );
    resumes_bit_for_bit(
        &example("slider_crank_clearance_joints.toml", 200, 1),
        23,
        150,
    );
    // Simplified Newton keeps the smooth stage's matrix across steps: the checkpoint keeps
    // where it was formed, and the resumed run forms the same one there again.
    resumes_bit_for_bit(
        &example_edited(
            "slider_crank_clearance_joints.toml",
            200,
            1,
            "rho_inf = 0.8",
            "rho_inf = 0.8\nnewton = \"simplified\"",
        ),
        23,
        150,
    );
    // Redundant joints (Bricard): the joints' rank deficit at the start of a step, which makes
    // the smooth stage solve every Newton matrix by the SVD at that deficit, is in the memory.
    resumes_bit_for_bit(
        &example_edited(
            "benchmarks/a04_bricard.toml",
            200,
            1,
            "scheme = \"soi2_generalized_alpha\"",
            "scheme = \"ns_generalized_alpha\"\nrho_inf = 0.8",
        ),
        23,
        150,
    );
}

#[test]
fn soi2_resumes_bit_for_bit() {
    // Simplified Newton keeps LU factors across steps; the pattern h/3, 2h/3 with (14)
    // adjustments makes the schedule position and a_α matter.
    resumes_bit_for_bit(&example("pendulum_soi2.toml", 300, 4), 31, 200);
    resumes_bit_for_bit(&example("slider_crank_hht.toml", 300, 3), 43, 260);
    resumes_bit_for_bit(&example("pendulum_lagrangian.toml", 200, 2), 17, 120);
}

/// `example(name, steps, every)` with `from` replaced by `to` in its text.
fn example_edited(name: &str, steps: u64, every: u64, from: &str, to: &str) -> JobSpec {
    let path = format!("{}/../../examples/{name}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains(from), "{name} has no {from:?}");
    let mut spec: JobSpec = toml::from_str(&text.replace(from, to)).unwrap();
    let time = spec.time.as_mut().unwrap();
    time.t_end = Some(time.t_end.unwrap().min(steps as f64 * time.h));
    spec.output.every = every;
    spec
}

#[test]
fn banded_contacts_and_the_contact_region_resume_bit_for_bit() {
    // The string on its bridge: the banded solver's warm start (the active dofs of its last
    // solution) and the contact-region grid are in the checkpoint. The first impacts are
    // near step 300; the checkpoints land while the string rides the bridge.
    let spec = example("string_bridge.toml", 1200, 3);
    assert!(Job::from_spec(&spec).unwrap().checkpoints());
    assert_eq!(resumes_bit_for_bit(&spec, 150, 800), 750);
    // The nonsmooth HHT on the same string (the filtered impulse map).
    let hht = example_edited(
        "string_bridge.toml",
        1200,
        3,
        "scheme = \"moreau_jean\"\ntheta = 0.5",
        "scheme = \"ns_hht\"\nalpha = 0.1",
    );
    assert!(Job::from_spec(&hht).unwrap().checkpoints());
    assert_eq!(resumes_bit_for_bit(&hht, 130, 700), 650);
}

#[test]
fn wfem_resumes_bit_for_bit() {
    resumes_bit_for_bit(&example("wfem_dep_bar.toml", 2000, 9), 301, 1500);
}

/// The checkpoint of a run of `bar.toml` after `step` steps, with its job.
fn bar_checkpoint(step: u64) -> (Job, Vec<u8>) {
    let spec = example("bar.toml", 200, 1);
    let job = Job::from_spec(&spec).unwrap();
    let mut cut = Interrupted {
        rec: Recorder::default(),
        period: step,
        stop: step + 1,
        last: None,
    };
    let _ = job::run(&job, 1, &mut cut);
    (job, cut.last.unwrap().1)
}

#[test]
fn a_damaged_or_foreign_checkpoint_is_refused_with_its_reason() {
    let (job, bytes) = bar_checkpoint(50);
    assert!(job.read_checkpoint(&bytes).is_ok());

    let mut flipped = bytes.clone();
    let last = flipped.len() - 1;
    flipped[last] ^= 0x01;
    assert!(matches!(
        job.read_checkpoint(&flipped),
        Err(CheckpointError::Checksum { .. })
    ));

    let truncated = &bytes[..bytes.len() - 10];
    assert!(matches!(
        job.read_checkpoint(truncated),
        Err(CheckpointError::Truncated { .. })
    ));

    assert_eq!(
        job.read_checkpoint(b"PK\x03\x04 not a checkpoint")
            .unwrap_err(),
        CheckpointError::Magic
    );

    let mut version = bytes.clone();
    version[8..12].copy_from_slice(&(FORMAT_VERSION + 1).to_le_bytes());
    assert_eq!(
        job.read_checkpoint(&version).unwrap_err(),
        CheckpointError::Version {
            expected: FORMAT_VERSION,
            found: FORMAT_VERSION + 1
        }
    );

    // Another spec (one parameter changed) refuses it; the checkpoint period does not count.
    let mut other = job.spec().clone();
    other.integrator = toml::from_str("scheme = \"moreau_jean\"\ntheta = 0.6").unwrap();
    let other = Job::from_spec(&other).unwrap();
    assert!(matches!(
        other.read_checkpoint(&bytes),
        Err(CheckpointError::Spec { .. })
    ));
    let mut period = job.spec().clone();
    period.output.checkpoint_seconds = Some(5.0);
    period.output.checkpoint_steps = Some(10);
    assert!(
        Job::from_spec(&period)
            .unwrap()
            .read_checkpoint(&bytes)
            .is_ok()
    );
}

#[test]
fn a_checkpoint_of_another_job_is_refused_before_any_step() {
    let (job, bytes) = bar_checkpoint(20);
    let checkpoint = job.read_checkpoint(&bytes).unwrap();
    assert_eq!(checkpoint.kind(), RunKind::Linear);
    let wave = Job::from_spec(&example("wfem_dep_bar.toml", 100, 1)).unwrap();
    let mut rec = Recorder::default();
    let err = job::resume(&wave, 1, &mut rec, &checkpoint).unwrap_err();
    assert!(
        matches!(err, RunError::Checkpoint(CheckpointError::Spec { .. })),
        "{err}"
    );
    assert!(rec.rows.is_empty() && rec.columns.is_empty());
}

#[test]
fn checkpoint_period_fields_are_checked() {
    let mut spec = example("bar.toml", 10, 1);
    spec.output.checkpoint_seconds = Some(0.0);
    let e = Job::from_spec(&spec).unwrap_err();
    assert_eq!(e.field, "output.checkpoint_seconds");
    spec.output.checkpoint_seconds = None;
    spec.output.checkpoint_steps = Some(0);
    let e = Job::from_spec(&spec).unwrap_err();
    assert_eq!(e.field, "output.checkpoint_steps");
}
