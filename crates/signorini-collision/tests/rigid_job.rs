//! A `rigid_bodies` job through the job API with parry's detectors: the rigid-body columns, and a run
//! interrupted and resumed from a checkpoint's bytes equals the uninterrupted run bit for bit.

use signorini_collision::ParryDetectors;
use signorini_core::checkpoint::Checkpoint;
use signorini_core::job::{self, Job};
use signorini_core::observer::{Columns, Observer, Progress, Recorder, StepRecord};
use signorini_core::outcome::RunError;
use signorini_core::spec::JobSpec;
use std::ops::ControlFlow;

/// A box thrown spinning onto a floor next to a ball: impacts, sliding, rolling, four-corner
/// contacts.
fn spec() -> JobSpec {
    serde_json::from_value(serde_json::json!({
        "model": {
            "scene": "rigid_bodies",
            "contact": { "friction": 0.4, "restitution": 0.3, "margin": 1e-6 },
            "bodies": [
                { "name": "cube", "shape": { "kind": "box", "half_extents": [0.1, 0.1, 0.1] },
                  "density": 500.0, "position": [0.0, 0.0, 0.3],
                  "velocity": [1.0, 0.2, 0.0], "angular_velocity": [0.5, 1.0, 3.0] },
                { "name": "ball", "shape": { "kind": "sphere", "radius": 0.1 }, "density": 800.0,
                  "position": [0.5, 0.0, 0.1], "velocity": [-1.0, 0.0, 0.0] },
                { "name": "floor", "shape": { "kind": "half_space", "normal": [0.0, 0.0, 1.0] } }
            ]
        },
        "integrator": { "scheme": "moreau_jean" },
        "time": { "h": 1e-3, "steps": 600 },
        "output": { "every": 7 }
    }))
    .unwrap()
}

struct Interrupted {
    rec: Recorder,
    stop: u64,
    last: Option<Vec<u8>>,
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
        p.done.is_multiple_of(100)
    }
    fn checkpoint(&mut self, c: &mut Checkpoint) {
        self.last = Some(c.encode().unwrap());
    }
}

#[test]
fn a_rigid_run_has_the_section_18_columns_and_resumes_bit_for_bit() {
    let job = Job::from_spec(&spec()).unwrap();
    let mut whole = Recorder::default();
    let full = job::run_with_detectors(&job, 1, &mut whole, None, &ParryDetectors).unwrap();
    let names = whole.columns.names();
    for c in [
        "cube_x",
        "cube_qw",
        "cube_qz",
        "cube_vx",
        "cube_wz",
        "ball_z",
        "floor_x",
        "kinetic",
        "potential",
        "energy",
        "work_ext",
        "work_contact",
        "work_friction",
        "energy_error",
        "contacts",
        "max_penetration",
    ] {
        assert!(
            names.iter().any(|n| n == c),
            "column {c} missing: {names:?}"
        );
    }
    // The ledger closes at round-off in every recorded step, through impacts and sliding.
    let scale = whole.column("energy").unwrap()[0].abs();
    assert!(
        whole
            .column("energy_error")
            .unwrap()
            .iter()
            .all(|e| e.abs() <= 1e-11 * scale)
    );
    assert!(whole.column("contacts").unwrap().iter().any(|c| *c >= 4.0));

    let mut cut = Interrupted {
        rec: Recorder::default(),
        stop: 350,
        last: None,
    };
    let stopped = job::run_with_detectors(&job, 1, &mut cut, None, &ParryDetectors);
    assert!(
        matches!(stopped, Err(RunError::Stopped { .. })),
        "{stopped:?}"
    );
    let fresh = Job::from_spec(&spec()).unwrap();
    let checkpoint = fresh.read_checkpoint(&cut.last.unwrap()).unwrap();
    assert_eq!(checkpoint.step(), 300);
    let kept = checkpoint.records() as usize;
    let mut rest = Recorder::default();
    let resumed =
        job::run_with_detectors(&fresh, 1, &mut rest, Some(&checkpoint), &ParryDetectors).unwrap();
    let mut rows = cut.rec.rows[..kept].to_vec();
    rows.extend(rest.rows.iter().cloned());
    let bits = |rows: &[Vec<f64>]| -> Vec<Vec<u64>> {
        rows.iter()
            .map(|r| r.iter().map(|x| x.to_bits()).collect())
            .collect()
    };
    assert_eq!(bits(&rows), bits(&whole.rows));
    assert_eq!(
        serde_json::to_string(&resumed.summary).unwrap(),
        serde_json::to_string(&full.summary).unwrap()
    );
}
