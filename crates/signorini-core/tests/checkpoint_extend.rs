//! Extending a finished run: the checkpoint a run of N₁ steps hands out after its last step,
//! continued by the same spec with a later end (N₂ steps), gives the steps after N₁ of one run
//! of N₂ steps bit for bit: every recorded value of every column (the energy ledger included),
//! the summary and the chart data. The spec hash leaves the run's end out
//! (`signorini_core::job::spec_hash`), so the checkpoint is accepted; any other change of the
//! spec still refuses it.
//!
//! Not so for SOI2: its schedule shortens the last step to land on `t_end` exactly (`t_end − t`
//! instead of `h`, a round-off apart), so a run to t₁ and a run to t₂ part at t₁; the service
//! refuses to extend an SOI2 job. WFEM sums the works since the last record, so its first run
//! must end on a recorded step (the service checks it).

// The test reads the examples from disk; the core library itself does no I/O.
#![allow(clippy::disallowed_methods)]

use signorini_core::checkpoint::{Checkpoint, CheckpointError};
use signorini_core::job::{self, Job};
use signorini_core::observer::{Columns, Observer, Progress, Recorder, StepRecord};
use signorini_core::outcome::RunOutput;
use signorini_core::spec::JobSpec;
use std::ops::ControlFlow;

/// An example spec ending after `steps` steps (as `steps`, or as `t_end` if it gives one),
/// recording every `every`-th.
fn example(name: &str, steps: u64, every: u64) -> JobSpec {
    let path = format!("{}/../../examples/{name}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap();
    let mut spec: JobSpec = toml::from_str(&text).unwrap();
    spec.output.every = every;
    ending(&spec, steps)
}

/// `spec` ending after `steps` steps.
fn ending(spec: &JobSpec, steps: u64) -> JobSpec {
    let mut spec = spec.clone();
    let time = spec.time.as_mut().unwrap();
    match time.steps {
        Some(_) => time.steps = Some(steps),
        None => time.t_end = Some(steps as f64 * time.h),
    }
    spec
}

/// Records everything and keeps the checkpoint handed out after the last step.
#[derive(Default)]
struct Final {
    rec: Recorder,
    last: Option<Vec<u8>>,
}

impl Observer for Final {
    fn start(&mut self, columns: &Columns) {
        self.rec.start(columns);
    }
    fn observe(&mut self, record: &StepRecord<'_>) -> ControlFlow<()> {
        self.rec.observe(record)
    }
    fn checkpoint_due(&mut self, p: Progress) -> bool {
        p.done == p.total
    }
    fn checkpoint(&mut self, c: &mut Checkpoint) {
        self.last = Some(c.encode().unwrap());
    }
}

fn bits(rows: &[Vec<f64>]) -> Vec<Vec<u64>> {
    rows.iter()
        .map(|r| r.iter().map(|x| x.to_bits()).collect())
        .collect()
}

fn printed(out: &RunOutput) -> (String, String) {
    (
        serde_json::to_string(&out.summary).unwrap(),
        format!("{:?}", out.charts),
    )
}

/// Runs `spec` to `n1` steps (or to `n1 h` for a spec ending by time), continues its final
/// checkpoint to `n2`, and compares with one run to `n2`: the rows after the first run's last
/// step, the summary, and (when the first run recorded no extra last row, its last step a
/// multiple of `every`) the chart data.
fn extends_bit_for_bit(spec: &JobSpec, n1: u64, n2: u64) {
    let first = Job::from_spec(&ending(spec, n1)).unwrap();
    let mut head = Final::default();
    job::run(&first, 1, &mut head).unwrap();
    let bytes = head.last.expect("a checkpoint after the last step");
    // The step count of the first run (a variable-step schedule ends by time).
    let n1 = *head.rec.steps.last().unwrap();

    let long = Job::from_spec(&ending(spec, n2)).unwrap();
    let mut whole = Recorder::default();
    let full = job::run(&long, 1, &mut whole).unwrap();

    let checkpoint = long.read_checkpoint(&bytes).unwrap();
    assert_eq!(checkpoint.step(), n1);
    assert!(whole.steps.last().unwrap() > &n1);
    let mut rest = Recorder::default();
    let extended = job::resume(&long, 1, &mut rest, &checkpoint).unwrap();

    let after = whole.steps.iter().position(|&s| s > n1).unwrap();
    assert_eq!(rest.columns, whole.columns);
    assert_eq!(rest.steps, whole.steps[after..]);
    assert_eq!(
        rest.t.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
        whole.t[after..]
            .iter()
            .map(|x| x.to_bits())
            .collect::<Vec<_>>()
    );
    for (i, (a, b)) in bits(&rest.rows)
        .iter()
        .zip(bits(&whole.rows[after..]))
        .enumerate()
    {
        assert_eq!(*a, b, "record of step {} differs", rest.steps[i]);
    }
    assert_eq!(rest.rows.len(), whole.rows.len() - after);
    let (summary, charts) = printed(&extended);
    assert_eq!(summary, printed(&full).0);
    if n1.is_multiple_of(spec.output.every) {
        assert_eq!(charts, printed(&full).1);
    }
}

#[test]
fn moreau_jean_extends_bit_for_bit() {
    extends_bit_for_bit(&example("bar.toml", 0, 7), 350, 600);
    extends_bit_for_bit(&example("chain_rough_wall.toml", 0, 3), 201, 500);
    extends_bit_for_bit(&example("linear.toml", 0, 1), 222, 400);
}

#[test]
fn alpha_family_extends_bit_for_bit() {
    extends_bit_for_bit(&example("bar_ns_generalized_alpha.toml", 0, 5), 450, 600);
    extends_bit_for_bit(&example("chain_ns_hht.toml", 0, 4), 301, 500);
    extends_bit_for_bit(
        &example("bar_newmark_position_contact.toml", 0, 3),
        300,
        600,
    );
}

#[test]
fn nonlinear_schemes_extend_bit_for_bit() {
    extends_bit_for_bit(&example("rocking_block.toml", 0, 3), 300, 400);
    extends_bit_for_bit(
        &example("rocking_block_ns_generalized_alpha.toml", 0, 3),
        200,
        300,
    );
}

#[test]
fn wfem_extends_bit_for_bit_from_a_recorded_step() {
    // WFEM sums the works since the last record: the first run must end on a recorded step
    // (a multiple of `every`), where a run to the later end records too.
    extends_bit_for_bit(&example("wfem_dep_bar.toml", 0, 9), 1503, 2000);
}

#[test]
fn a_longer_run_takes_the_final_checkpoint_another_spec_does_not() {
    let spec = example("bar.toml", 0, 7);
    let first = Job::from_spec(&ending(&spec, 100)).unwrap();
    let mut head = Final::default();
    job::run(&first, 1, &mut head).unwrap();
    let bytes = head.last.unwrap();
    assert!(
        Job::from_spec(&ending(&spec, 300))
            .unwrap()
            .read_checkpoint(&bytes)
            .is_ok()
    );
    let mut other = ending(&spec, 300);
    other.time.as_mut().unwrap().h *= 0.5;
    assert!(matches!(
        Job::from_spec(&other).unwrap().read_checkpoint(&bytes),
        Err(CheckpointError::Spec { .. })
    ));
}
